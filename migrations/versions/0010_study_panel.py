"""A study participant's recruiting-panel identifiers (from the panel's link) and the seconds they
waited in the lobby (for paying waiting time).

Revision ID: 0010
Revises: 0009
"""

import sqlalchemy as sa
from alembic import op

revision = "0010"
down_revision = "0009"
branch_labels = None
depends_on = None

PANEL_COLUMNS = ("panel_participant", "panel_study", "panel_session")


def upgrade() -> None:
    with op.batch_alter_table("study_participant") as batch:
        batch.add_column(sa.Column("lobby_waited_s", sa.Float(), nullable=False, server_default="0"))
        batch.add_column(sa.Column("lobby_waited_to", sa.DateTime(timezone=True), nullable=True))
        for column in PANEL_COLUMNS:
            batch.add_column(sa.Column(column, sa.String(200), nullable=True))


def downgrade() -> None:
    with op.batch_alter_table("study_participant") as batch:
        for column in (*PANEL_COLUMNS, "lobby_waited_to", "lobby_waited_s"):
            batch.drop_column(column)

"""Who holds the Commander's seat ('human' or an agent, as `driver` says for the Driver's), and the
study a trial belongs to (its name; none for trials made outside a study).

Revision ID: 0005
Revises: 0004
"""

import sqlalchemy as sa
from alembic import op

revision = "0005"
down_revision = "0004"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("trial") as batch:
        batch.add_column(sa.Column("commander", sa.String(40), nullable=False, server_default="human"))
        batch.add_column(sa.Column("study", sa.String(80), nullable=True))
        batch.create_index("ix_trial_study", ["study"])


def downgrade() -> None:
    with op.batch_alter_table("trial") as batch:
        batch.drop_index("ix_trial_study")
        batch.drop_column("study")
        batch.drop_column("commander")

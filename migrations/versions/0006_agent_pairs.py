"""A trial with agents in both seats has no team: `trial.team_id` may be empty.

Revision ID: 0006_agent_pairs
Revises: 0005
"""

import sqlalchemy as sa
from alembic import op

revision = "0006_agent_pairs"
down_revision = "0005"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("trial") as batch:
        batch.alter_column("team_id", existing_type=sa.Integer(), nullable=True)


def downgrade() -> None:
    # An agent pair has no team to give back, and nothing recorded is thrown away: refuse instead.
    pairs = op.get_bind().execute(sa.text("select count(*) from trial where team_id is null")).scalar()
    if pairs:
        raise RuntimeError(f"{pairs} trials have agents in both seats and no team; export and delete them first")
    with op.batch_alter_table("trial") as batch:
        batch.alter_column("team_id", existing_type=sa.Integer(), nullable=False)

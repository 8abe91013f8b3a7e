"""A trial with agents in both seats has no team: `trial.team_id` may be empty.

Revision ID: 0006_agent_pairs
Revises: 0005
"""

import sqlalchemy as sa
from alembic import context, op

revision = "0006_agent_pairs"
down_revision = "0005"
branch_labels = None
depends_on = None


def trial_as_of_0005() -> sa.Table:
    """The trial table as 0001-0005 left it. SQLite changes a column's nullability by copying the
    table, which online reads from the database; offline (`alembic upgrade head --sql`) there is
    none to read, so the copy is made from this."""
    return sa.Table(
        "trial",
        sa.MetaData(),
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("team_id", sa.Integer, sa.ForeignKey("team.id"), nullable=False),
        sa.Column("maze", sa.String(80), nullable=False),
        sa.Column("targets", sa.JSON, nullable=False),
        sa.Column("backend", sa.String(40), nullable=False),
        sa.Column("driver", sa.String(40), nullable=False),
        sa.Column("commander_id", sa.Integer, sa.ForeignKey("participant.id"), nullable=True),
        sa.Column("driver_id", sa.Integer, sa.ForeignKey("participant.id"), nullable=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("phase", sa.String(16), nullable=False),
        sa.Column("active_s", sa.Float, nullable=True),
        sa.Column("moves", sa.Integer, nullable=False),
        sa.Column("excluded_reason", sa.Text, nullable=True),
        sa.Column("commander", sa.String(40), nullable=False, server_default="human"),
        sa.Column("study", sa.String(80), nullable=True),
        sa.Index("ix_trial_study", "study"),
    )


def upgrade() -> None:
    copy_from = trial_as_of_0005() if context.is_offline_mode() else None
    with op.batch_alter_table("trial", copy_from=copy_from) as batch:
        batch.alter_column("team_id", existing_type=sa.Integer(), nullable=True)


def downgrade() -> None:
    # An agent pair has no team to give back, and nothing recorded is thrown away: refuse instead.
    pairs = op.get_bind().execute(sa.text("select count(*) from trial where team_id is null")).scalar()
    if pairs:
        raise RuntimeError(f"{pairs} trials have agents in both seats and no team; export and delete them first")
    with op.batch_alter_table("trial") as batch:
        batch.alter_column("team_id", existing_type=sa.Integer(), nullable=False)

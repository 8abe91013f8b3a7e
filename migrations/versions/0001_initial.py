"""The platform's tables: people, teams, robots, trials and their event log and frames.

Revision ID: 0001
Revises:
"""

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None


def upgrade() -> None:
    ts = sa.DateTime(timezone=True)
    op.create_table(
        "experimenter",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("name", sa.String(80), nullable=False, unique=True),
        sa.Column("password_hash", sa.String(255), nullable=False),
        sa.Column("created_at", ts, nullable=False),
    )
    op.create_table(
        "participant",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("name", sa.String(80), nullable=False, unique=True),
        sa.Column("created_at", ts, nullable=False),
    )
    op.create_table(
        "team",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("name", sa.String(80), nullable=False, unique=True),
        sa.Column("member_a_id", sa.Integer, sa.ForeignKey("participant.id"), nullable=False),
        sa.Column("member_b_id", sa.Integer, sa.ForeignKey("participant.id"), nullable=False),
        sa.Column("created_at", ts, nullable=False),
    )
    op.create_table(
        "robot",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("name", sa.String(80), nullable=False, unique=True),
        sa.Column("token_hash", sa.String(255), nullable=False),
        sa.Column("role", sa.String(16), nullable=False),
        sa.Column("created_at", ts, nullable=False),
    )
    op.create_table(
        "trial",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("team_id", sa.Integer, sa.ForeignKey("team.id"), nullable=False),
        sa.Column("maze", sa.String(80), nullable=False),
        sa.Column("targets", sa.JSON, nullable=False),
        sa.Column("backend", sa.String(40), nullable=False),
        sa.Column("driver", sa.String(40), nullable=False),
        sa.Column("commander_id", sa.Integer, sa.ForeignKey("participant.id"), nullable=True),
        sa.Column("driver_id", sa.Integer, sa.ForeignKey("participant.id"), nullable=True),
        sa.Column("created_at", ts, nullable=False),
        sa.Column("phase", sa.String(16), nullable=False),
        sa.Column("active_s", sa.Float, nullable=True),
        sa.Column("moves", sa.Integer, nullable=False),
    )
    op.create_table(
        "event",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("trial_id", sa.Integer, sa.ForeignKey("trial.id"), nullable=False),
        sa.Column("seq", sa.Integer, nullable=False),
        sa.Column("kind", sa.String(32), nullable=False),
        sa.Column("t_ns", sa.BigInteger, nullable=False),
        sa.Column("payload", sa.JSON, nullable=False),
        sa.UniqueConstraint("trial_id", "seq", name="uq_event_trial_seq"),
    )
    op.create_index("ix_event_trial_id", "event", ["trial_id"])
    op.create_table(
        "frame",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("trial_id", sa.Integer, sa.ForeignKey("trial.id"), nullable=False),
        sa.Column("seq", sa.Integer, nullable=False),
        sa.Column("source", sa.String(16), nullable=False),
        sa.Column("path", sa.Text, nullable=False),
        sa.Column("capture_ns", sa.BigInteger, nullable=False),
        sa.Column("width", sa.Integer, nullable=False),
        sa.Column("height", sa.Integer, nullable=False),
    )
    op.create_index("ix_frame_trial_id", "frame", ["trial_id"])


def downgrade() -> None:
    for table in ("frame", "event", "trial", "robot", "team", "participant", "experimenter"):
        op.drop_table(table)

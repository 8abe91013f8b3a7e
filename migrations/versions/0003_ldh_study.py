"""LDH human studies: their frozen instances, invited participants and event log.

Revision ID: 0003
Revises: 0002
"""

import sqlalchemy as sa
from alembic import op

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None


def upgrade() -> None:
    ts = sa.DateTime(timezone=True)
    op.create_table(
        "ldh_study",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("name", sa.String(80), nullable=False),
        sa.Column("source", sa.Text, nullable=False),
        sa.Column("split", sa.String(16), nullable=False),
        sa.Column("variant", sa.String(16), nullable=False),
        sa.Column("experimenter_id", sa.Integer, sa.ForeignKey("experimenter.id"), nullable=False),
        sa.Column("created_at", ts, nullable=False),
    )
    op.create_table(
        "ldh_study_instance",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("study_id", sa.Integer, sa.ForeignKey("ldh_study.id"), nullable=False, index=True),
        sa.Column("position", sa.Integer, nullable=False),
        sa.Column("inst_idx", sa.Integer, nullable=False),
        sa.Column("run", sa.String(80), nullable=False),
        sa.Column("dialog", sa.JSON, nullable=False),
        sa.Column("true_x", sa.Float, nullable=False),
        sa.Column("true_y", sa.Float, nullable=False),
        sa.Column("true_heading", sa.Float, nullable=True),
        sa.UniqueConstraint("study_id", "position", name="uq_ldh_instance_position"),
    )
    op.create_table(
        "ldh_study_participant",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("study_id", sa.Integer, sa.ForeignKey("ldh_study.id"), nullable=False, index=True),
        sa.Column("name", sa.String(80), nullable=False),
        sa.Column("created_at", ts, nullable=False),
        sa.UniqueConstraint("study_id", "name", name="uq_ldh_participant_name"),
    )
    op.create_table(
        "ldh_study_event",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("study_id", sa.Integer, sa.ForeignKey("ldh_study.id"), nullable=False, index=True),
        sa.Column("seq", sa.Integer, nullable=False),
        sa.Column("kind", sa.String(32), nullable=False),
        sa.Column("t_ns", sa.BigInteger, nullable=False),
        sa.Column("payload", sa.JSON, nullable=False),
        sa.UniqueConstraint("study_id", "seq", name="uq_ldh_event_study_seq"),
    )


def downgrade() -> None:
    for table in ("ldh_study_event", "ldh_study_participant", "ldh_study_instance", "ldh_study"):
        op.drop_table(table)

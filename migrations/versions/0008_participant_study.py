"""Participant studies: who consented under which code (a real name optional, erasable), the
study's pseudonymous log, and the questionnaire after each trial.

Revision ID: 0008
Revises: 0007
"""

import sqlalchemy as sa
from alembic import op

revision = "0008"
down_revision = "0007"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "study_participant",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("study", sa.String(80), nullable=False),
        sa.Column("participant_id", sa.Integer(), sa.ForeignKey("participant.id"), nullable=False, unique=True),
        sa.Column("real_name", sa.String(120), nullable=True),
        sa.Column("consent_version", sa.String(40), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("completed_at", sa.DateTime(timezone=True), nullable=True),
        sa.Column("withdrawn_at", sa.DateTime(timezone=True), nullable=True),
        sa.Column("lobby_since", sa.DateTime(timezone=True), nullable=True),
        sa.Column("lobby_seen", sa.DateTime(timezone=True), nullable=True),
    )
    op.create_index("ix_study_participant_study", "study_participant", ["study"])
    op.create_table(
        "study_event",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("study", sa.String(80), nullable=False),
        sa.Column("participant_id", sa.Integer(), sa.ForeignKey("participant.id"), nullable=True),
        sa.Column("kind", sa.String(32), nullable=False),
        sa.Column("t_ns", sa.BigInteger(), nullable=False),
        sa.Column("payload", sa.JSON(), nullable=False),
    )
    op.create_index("ix_study_event_study", "study_event", ["study"])
    op.create_table(
        "study_answer",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("study_participant_id", sa.Integer(), sa.ForeignKey("study_participant.id"), nullable=False),
        sa.Column("trial_id", sa.Integer(), sa.ForeignKey("trial.id"), nullable=False),
        sa.Column("ratings", sa.JSON(), nullable=False),
        sa.Column("free_text", sa.JSON(), nullable=True),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.UniqueConstraint("study_participant_id", "trial_id", name="uq_study_answer_trial"),
    )
    op.create_index("ix_study_answer_study_participant_id", "study_answer", ["study_participant_id"])


def downgrade() -> None:
    op.drop_table("study_answer")
    op.drop_index("ix_study_event_study", "study_event")
    op.drop_table("study_event")
    op.drop_index("ix_study_participant_study", "study_participant")
    op.drop_table("study_participant")

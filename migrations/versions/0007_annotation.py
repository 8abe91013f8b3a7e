"""Annotation: the annotator role on accounts, the annotations' own event log and the
annotators' queues (issue 25).

Revision ID: 0007
Revises: 0006_agent_pairs
"""

import sqlalchemy as sa
from alembic import op

revision = "0007"
down_revision = "0006_agent_pairs"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("experimenter") as batch:
        batch.add_column(sa.Column("role", sa.String(16), nullable=False, server_default="experimenter"))
    op.create_table(
        "annotation_event",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("trial_id", sa.Integer, sa.ForeignKey("trial.id"), nullable=False),
        sa.Column("annotator_id", sa.Integer, sa.ForeignKey("experimenter.id"), nullable=False),
        sa.Column("kind", sa.String(32), nullable=False),
        sa.Column("t_ns", sa.BigInteger, nullable=False),
        sa.Column("payload", sa.JSON, nullable=False),
        sa.Column("revises", sa.Integer, nullable=True),
    )
    op.create_index("ix_annotation_event_trial_id", "annotation_event", ["trial_id"])
    op.create_table(
        "annotation_assignment",
        sa.Column("id", sa.Integer, primary_key=True),
        sa.Column("trial_id", sa.Integer, sa.ForeignKey("trial.id"), nullable=False),
        sa.Column("annotator_id", sa.Integer, sa.ForeignKey("experimenter.id"), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.UniqueConstraint("trial_id", "annotator_id", name="uq_assignment_trial_annotator"),
    )
    op.create_index("ix_annotation_assignment_trial_id", "annotation_assignment", ["trial_id"])
    op.create_index("ix_annotation_assignment_annotator_id", "annotation_assignment", ["annotator_id"])


def downgrade() -> None:
    op.drop_table("annotation_assignment")
    op.drop_index("ix_annotation_event_trial_id", "annotation_event")
    op.drop_table("annotation_event")
    with op.batch_alter_table("experimenter") as batch:
        batch.drop_column("role")

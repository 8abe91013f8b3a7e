"""The database side of a study's annotation: the agreement between its trials' annotators."""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.annotation.agreement import AgreementNumbers, agreement
from app.annotation.log import AnnotationLog
from app.db.models import Experimenter
from app.export.source import exported_trial_ids


def study_agreement(db: Session, log: AnnotationLog, study: str) -> AgreementNumbers:
    """Agreement over the study's trials that are annotated, exported and reported (finished, not
    excluded), with the annotators by their accounts' names."""
    names = {i: n for i, n in db.execute(select(Experimenter.id, Experimenter.name))}
    return agreement(log.states(exported_trial_ids(db, study=study)), names)

"""The database side of a study's annotation: its trials and the accounts' names."""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.db.models import Experimenter, Trial
from sim.trial.vocabulary import Phase


def study_trial_ids(db: Session, study: str) -> list[int]:
    """The study's finished trials not excluded (those annotated, exported and reported)."""
    query = select(Trial.id).where(Trial.study == study, Trial.phase == Phase.FINISHED, Trial.excluded_reason.is_(None))
    return list(db.scalars(query.order_by(Trial.id)))


def annotator_names(db: Session) -> dict[int, str]:
    return {i: n for i, n in db.execute(select(Experimenter.id, Experimenter.name))}

"""The study page's trials: each one's kind (the practice, scored, excluded, aborted, or still
going on) and who held its seats, by participant code."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.db.models import Participant, Trial
from app.study.lobby import PRACTICE_REASON
from app.trial.setup import never_joined
from sim.trial.vocabulary import Phase


class TrialKind(StrEnum):
    practice = "practice"  # set aside from scores, no questionnaire
    scored = "scored"  # finished: on the leaderboard and in the exports
    excluded = "excluded"  # set aside by the experimenter, with a reason
    aborted = "aborted"
    never_joined = "never joined"  # aborted before a seat was opened: no one's in the plan
    live = "live"


@dataclass(frozen=True)
class StudyTrial:
    trial: Trial
    kind: TrialKind
    commander: str  # the seat holder's participant code
    driver: str


def study_trials(db: Session, study: str) -> list[StudyTrial]:
    trials = list(db.scalars(select(Trial).where(Trial.study == study).order_by(Trial.id)))
    unopened = never_joined(db, [t.id for t in trials])
    ids = {t.commander_id for t in trials} | {t.driver_id for t in trials}
    rows = db.execute(select(Participant.id, Participant.name).where(Participant.id.in_(ids)))
    codes: dict[int | None, str] = {pid: code for pid, code in rows}
    return [
        StudyTrial(t, _kind(t, t.id in unopened), codes.get(t.commander_id, "–"), codes.get(t.driver_id, "–"))
        for t in trials
    ]


def _kind(trial: Trial, unopened: bool) -> TrialKind:
    if trial.excluded_reason == PRACTICE_REASON:
        return TrialKind.practice
    if trial.excluded_reason is not None:
        return TrialKind.excluded
    if trial.phase == Phase.FINISHED:
        return TrialKind.scored
    if trial.phase == Phase.ABORTED:
        return TrialKind.never_joined if unopened else TrialKind.aborted
    return TrialKind.live

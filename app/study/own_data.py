"""Everything recorded about one study participant, for them to download from their page (the
right of access): their enrolment (consent and its version, their name and panel identifiers
where kept), the study's log of them, their questionnaire answers, and of each of their trials
the events their seat made (what they wrote, moved, marked, claimed or judged)."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import TypedDict

from sqlalchemy import select

from app.db.models import Event, StudyAnswer, StudyEvent, StudyParticipant
from app.study.config import StudyOutcome
from app.study.enrolment import Enrolment
from app.study.lobby import PRACTICE_REASON, seat_of
from sim.trial.vocabulary import Role

# The events a seat makes without naming itself in the payload (chat, connects and bad messages do).
SEAT_ACTS = {
    Role.DRIVER: {"move_requested", "target_claimed"},
    Role.COMMANDER: {"localization", "target_confirmed", "target_rejected"},
}


def _at(t_ns: int) -> str:
    return datetime.fromtimestamp(t_ns / 1e9, UTC).isoformat()


def _iso(t: datetime | None) -> str | None:
    return None if t is None else t.isoformat()


class Panel(TypedDict):
    participant: str | None
    study: str | None
    session: str | None


class OwnAnswer(TypedDict):
    trial_id: int
    ratings: dict[str, int]
    free_text: dict[str, str] | None
    at: str | None


class OwnTrial(TypedDict):
    trial_id: int
    seat: Role
    maze: str
    phase: str
    practice: bool
    events: list[dict[str, object]]  # seq, kind, at and the event's own payload


class OwnData(TypedDict):
    """The participant's download (`/study/NAME/me/data.json`)."""

    study: str
    participant: str
    real_name: str | None
    panel: Panel
    consent_version: str
    enrolled_at: str | None
    completed_at: str | None
    outcome: StudyOutcome | None
    study_events: list[dict[str, object]]  # kind, at and the study event's own payload
    answers: list[OwnAnswer]
    trials: list[OwnTrial]


def own_data(enrolment: Enrolment, enrolled: StudyParticipant, code: str) -> OwnData:
    db = enrolment.db
    log = db.scalars(
        select(StudyEvent)
        .where(StudyEvent.study == enrolment.config.name, StudyEvent.participant_id == enrolled.participant_id)
        .order_by(StudyEvent.id)
    )
    answers = db.scalars(
        select(StudyAnswer).where(StudyAnswer.study_participant_id == enrolled.id).order_by(StudyAnswer.id)
    )
    trials: list[OwnTrial] = []
    for trial in enrolment.trials(enrolled):
        seat = seat_of(trial, enrolled.participant_id).role
        events = db.scalars(select(Event).where(Event.trial_id == trial.id).order_by(Event.seq))
        trials.append(
            {
                "trial_id": trial.id,
                "seat": seat,
                "maze": trial.maze,
                "phase": trial.phase,
                "practice": trial.excluded_reason == PRACTICE_REASON,
                "events": [
                    {"seq": e.seq, "kind": e.kind, "at": _at(e.t_ns), **e.payload}
                    for e in events
                    if e.payload.get("role") == seat or e.kind in SEAT_ACTS[seat]
                ],
            }
        )
    outcome = enrolment.outcome(enrolled)
    return {
        "study": enrolment.config.name,
        "participant": code,
        "real_name": enrolled.real_name,
        "panel": {
            "participant": enrolled.panel_participant,
            "study": enrolled.panel_study,
            "session": enrolled.panel_session,
        },
        "consent_version": enrolled.consent_version,
        "enrolled_at": _iso(enrolled.created_at),
        "completed_at": _iso(enrolled.completed_at),
        "outcome": outcome,
        "study_events": [{"kind": e.kind, "at": _at(e.t_ns), **e.payload} for e in log],
        "answers": [
            {"trial_id": a.trial_id, "ratings": a.ratings, "free_text": a.free_text, "at": _iso(a.created_at)}
            for a in answers
        ],
        "trials": trials,
    }

"""The experimenter's roster of a study for paying its participants: one row per participant with
the panel's identifiers, how their way ended and its code, their minutes in the study (consent to
the end of their way; one still in it: to now) and their minutes waited in the lobby. Written by
`export all --study NAME` (participants.csv) and the study page's download."""

from __future__ import annotations

import csv
import io
from dataclasses import asdict, dataclass
from datetime import datetime

from app.study.config import StudyOutcome
from app.study.enrolment import Enrolment
from app.study.lobby import aware, waited_s

COLUMNS = (
    "participant",
    "panel_participant",
    "panel_study",
    "panel_session",
    "outcome",
    "completion_code",
    "minutes_in_study",
    "minutes_in_lobby",
)


@dataclass(frozen=True)
class RosterRow:
    participant: str  # the pseudonymous code
    panel_participant: str | None
    panel_study: str | None
    panel_session: str | None
    outcome: StudyOutcome | None  # None: still in the study
    completion_code: str | None
    minutes_in_study: float
    minutes_in_lobby: float


def roster(enrolment: Enrolment, now: datetime) -> list[RosterRow]:
    rows = []
    for enrolled, code, _ in enrolment.participants():
        outcome = enrolment.outcome(enrolled)
        ended = enrolled.completed_at or enrolled.withdrawn_at
        in_study_s = ((now if ended is None else aware(ended)) - aware(enrolled.created_at)).total_seconds()
        rows.append(
            RosterRow(
                participant=code,
                panel_participant=enrolled.panel_participant,
                panel_study=enrolled.panel_study,
                panel_session=enrolled.panel_session,
                outcome=outcome,
                completion_code=None if outcome is None else enrolment.config.code_for(outcome),
                minutes_in_study=round(in_study_s / 60, 2),
                minutes_in_lobby=round(waited_s(enrolled) / 60, 2),
            )
        )
    return rows


def roster_csv(rows: list[RosterRow]) -> str:
    out = io.StringIO()
    writer = csv.DictWriter(out, COLUMNS, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: "" if v is None else v for k, v in asdict(row).items()})
    return out.getvalue()

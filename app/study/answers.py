"""A study's questionnaire answers as the experimenter reads them: each answer with the seat its
participant held, the partner (and the partner's seat, whom `partner_helpfulness` rates), and the
study version it was asked under, with that version's items; and each rating item's distribution
by seat. The study page, `export all --study NAME` and `report study` all read them from here."""

from __future__ import annotations

import csv
import io
import statistics
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TypedDict

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.db.models import Participant, StudyAnswer, StudyEvent, StudyParticipant, Trial
from app.study.config import RATING_SCALE, Question, QuestionKind, StudyFiles
from sim.trial.vocabulary import Role


class AnswerRow(TypedDict):
    trial_id: int
    trial_phase: str
    participant: str
    seat: str
    partner: str | None
    partner_seat: str
    study_version: int
    ratings: dict[str, int]
    free_text: dict[str, str]


class SeatRatings(TypedDict):
    n: int
    counts: dict[str, int]  # each rating of the scale ("1" to "5") -> how many gave it
    mean: float | None


class ItemRatings(TypedDict):
    kind: str
    prompt: str
    by_seat: dict[str, SeatRatings]


class AnswersFile(TypedDict):
    study: str
    questionnaires: dict[str, list[dict[str, object]]]  # version -> its items (`Question` as JSON)
    answers: list[AnswerRow]


@dataclass(frozen=True)
class Answer:
    trial_id: int
    trial_phase: str
    participant: str  # the participant's code, never a real name
    seat: Role
    partner: str | None  # the partner's code
    partner_seat: Role
    study_version: int  # the study's version when the questionnaire was answered
    ratings: dict[str, int]
    free_text: dict[str, str]  # empty where none was given, or the participant withdrew

    def row(self) -> AnswerRow:
        return {
            "trial_id": self.trial_id,
            "trial_phase": self.trial_phase,
            "participant": self.participant,
            "seat": str(self.seat),
            "partner": self.partner,
            "partner_seat": str(self.partner_seat),
            "study_version": self.study_version,
            "ratings": self.ratings,
            "free_text": self.free_text,
        }


def study_answers(db: Session, study: str) -> list[Answer]:
    """Every answer of the study, by trial and then participant code."""
    names = dict(db.execute(select(Participant.id, Participant.name)).all())
    versions = {
        (e.participant_id, e.payload.get("trial_id")): int(e.payload["study_version"])
        for e in db.scalars(select(StudyEvent).where(StudyEvent.study == study, StudyEvent.kind == "answered"))
    }
    rows = db.execute(
        select(StudyAnswer, StudyParticipant.participant_id, Trial)
        .join(StudyParticipant, StudyParticipant.id == StudyAnswer.study_participant_id)
        .join(Trial, Trial.id == StudyAnswer.trial_id)
        .where(StudyParticipant.study == study)
    ).all()
    answers = []
    for answer, pid, trial in rows:
        commands = trial.commander_id == pid
        partner_id = trial.driver_id if commands else trial.commander_id
        answers.append(
            Answer(
                trial_id=trial.id,
                trial_phase=trial.phase,
                participant=names[pid],
                seat=Role.COMMANDER if commands else Role.DRIVER,
                partner=names.get(partner_id) if partner_id is not None else None,
                partner_seat=Role.DRIVER if commands else Role.COMMANDER,
                study_version=versions[(pid, trial.id)],
                ratings=dict(answer.ratings),
                free_text=dict(answer.free_text or {}),
            )
        )
    return sorted(answers, key=lambda a: (a.trial_id, a.participant))


def asked(files: StudyFiles, study: str, answers: Sequence[Answer]) -> dict[int, list[Question]]:
    """The questionnaire of each study version the answers were given under (and the current one)."""
    current = files.load(study)
    return {
        v: files.version(study, v).questionnaire for v in sorted({a.study_version for a in answers} | {current.version})
    }


def items(questionnaires: dict[int, list[Question]]) -> list[Question]:
    """Every item any version asked, once, with its latest wording."""
    latest: dict[str, Question] = {}
    for version in sorted(questionnaires):
        for q in questionnaires[version]:
            latest.pop(q.id, None)
            latest[q.id] = q
    return list(latest.values())


def rating_distributions(answers: Sequence[Answer], questions: Sequence[Question]) -> dict[str, ItemRatings]:
    """Per rating item, per seat: how many gave each rating, their number and mean."""
    low, high = RATING_SCALE
    table: dict[str, ItemRatings] = {}
    for q in questions:
        if q.kind is QuestionKind.free_text:
            continue
        by_seat: dict[str, SeatRatings] = {}
        for seat in (Role.COMMANDER, Role.DRIVER):
            given = [a.ratings[q.id] for a in answers if a.seat == seat and q.id in a.ratings]
            by_seat[str(seat)] = {
                "n": len(given),
                "counts": {str(r): given.count(r) for r in range(low, high + 1)},
                "mean": statistics.fmean(given) if given else None,
            }
        table[q.id] = {"kind": str(q.kind), "prompt": q.prompt, "by_seat": by_seat}
    return table


def answers_json(study: str, answers: Sequence[Answer], questionnaires: dict[int, list[Question]]) -> AnswersFile:
    return {
        "study": study,
        "questionnaires": {
            str(v): [q.model_dump(mode="json") for q in questions] for v, questions in questionnaires.items()
        },
        "answers": [a.row() for a in answers],
    }


def answers_csv(study: str, answers: Sequence[Answer], questions: Sequence[Question]) -> str:
    """One row per answer, one column per item (its id; the JSON gives each version's wording)."""
    out = io.StringIO()
    fields = ["study", "study_version", "trial_id", "trial_phase", "participant", "seat", "partner", "partner_seat"]
    writer = csv.DictWriter(out, [*fields, *(q.id for q in questions)], lineterminator="\n")
    writer.writeheader()
    for a in answers:
        row = {k: v for k, v in a.row().items() if k in fields}
        writer.writerow({**row, "study": study, **a.ratings, **a.free_text})
    return out.getvalue()

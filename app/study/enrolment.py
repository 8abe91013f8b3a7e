"""Who takes part in a study: consent (recorded with the text's version), the participant code,
questionnaires after trials, completion and withdrawal (personal data erased, events kept)."""

from __future__ import annotations

import secrets
from dataclasses import dataclass
from datetime import UTC, datetime
from enum import StrEnum

from sqlalchemy import func, or_, select
from sqlalchemy.orm import Session

from app.clock import ServerClock
from app.db.models import Participant, StudyAnswer, StudyEvent, StudyParticipant, Trial
from app.i18n import Text
from app.study.config import RATING_SCALE, PanelIds, QuestionKind, StudyConfig, StudyOutcome
from app.study.lobby import PRACTICE_REASON, end_wait
from app.trial.setup import never_joined

CODE_ALPHABET = "ABCDEFGHJKLMNPQRSTUVWXYZ23456789"  # no 0/O, 1/I: read aloud and typed back
CODE_LENGTH = 6
MAX_FREE_TEXT = 2000


class StudyEventKind(StrEnum):
    consented = "consented"
    declined = "declined"
    answered = "answered"
    completed = "completed"  # the participant's way ended: `outcome` (a `StudyOutcome`), `trials` played
    withdrawn = "withdrawn"
    purged = "purged"  # the study's personal data deleted (`app.study.purge`): `participants` who had some


class AfterTrial(StrEnum):
    """Where a participant's seat page sends them once their trial is over."""

    questionnaire = "questionnaire"  # a trial they played, not yet rated
    lobby = "lobby"  # the practice, or a trial a partner never opened: straight on to the next
    study_page = "me"  # rated already, or not over yet: their page says what is next


class EnrolmentError(ValueError):
    """A participant's request that cannot be taken; nothing was recorded."""


class StudyFull(EnrolmentError):
    """The study has taken its `max_participants`."""


@dataclass(frozen=True)
class Enrolled:
    enrolment_id: int
    code: str


def new_code(db: Session) -> str:
    while True:
        code = "P-" + "".join(secrets.choice(CODE_ALPHABET) for _ in range(CODE_LENGTH))
        if db.scalar(select(Participant.id).where(Participant.name == code)) is None:
            return code


class Enrolment:
    """A study's participants, in one database session the caller commits."""

    def __init__(self, db: Session, clock: ServerClock, config: StudyConfig) -> None:
        self.db = db
        self.clock = clock
        self.config = config

    def _log(self, kind: StudyEventKind, participant_id: int | None, **payload: object) -> None:
        self.db.add(
            StudyEvent(
                study=self.config.name,
                participant_id=participant_id,
                kind=kind,
                t_ns=self.clock.now_ns(),
                payload={"study_version": self.config.version, **payload},
            )
        )

    def full(self) -> bool:
        """Whether the study has taken its `max_participants` (withdrawn ones count: they took part)."""
        cap = self.config.max_participants
        if cap is None:
            return False
        taken = self.db.scalar(
            select(func.count()).select_from(StudyParticipant).where(StudyParticipant.study == self.config.name)
        )
        return (taken or 0) >= cap

    def consent(self, panel: PanelIds | None = None) -> Enrolled:
        """A new participant who agreed to the consent text now shown: a code, no name yet (and the
        panel's identifiers where a panel's link brought them)."""
        if self.full():
            raise StudyFull(f"study {self.config.name!r} has taken all its {self.config.max_participants} participants")
        participant = Participant(name=new_code(self.db))
        self.db.add(participant)
        self.db.flush()
        enrolled = StudyParticipant(
            study=self.config.name, participant_id=participant.id, consent_version=self.config.consent.version
        )
        self.db.add(enrolled)
        if panel is not None:
            self.set_panel(enrolled, panel)
        self.db.flush()
        self._log(StudyEventKind.consented, participant.id, consent_version=self.config.consent.version)
        return Enrolled(enrolled.id, participant.name)

    def set_panel(self, enrolled: StudyParticipant, panel: PanelIds) -> None:
        """The panel's identifiers for this participant; one already stored is kept (a link opened again)."""
        enrolled.panel_participant = enrolled.panel_participant or panel.participant
        enrolled.panel_study = enrolled.panel_study or panel.study
        enrolled.panel_session = enrolled.panel_session or panel.session

    def decline(self) -> None:
        self._log(StudyEventKind.declined, None, consent_version=self.config.consent.version)

    def get(self, enrolment_id: int) -> StudyParticipant:
        enrolled = self.db.get(StudyParticipant, enrolment_id)
        if enrolled is None or enrolled.study != self.config.name:
            raise LookupError("this browser's study pass names no participant of this study")
        return enrolled

    def by_code(self, code: str) -> StudyParticipant:
        enrolled = self.db.scalar(
            select(StudyParticipant)
            .join(Participant, Participant.id == StudyParticipant.participant_id)
            .where(Participant.name == code.strip(), StudyParticipant.study == self.config.name)
        )
        if enrolled is None:
            raise LookupError(f"no participant {code.strip()[:80]!r} in study {self.config.name!r}")
        return enrolled

    def code(self, enrolled: StudyParticipant) -> str:
        return self.db.execute(select(Participant.name).where(Participant.id == enrolled.participant_id)).scalar_one()

    def set_real_name(self, enrolled: StudyParticipant, name: str) -> None:
        self._active(enrolled)
        name = name.strip()
        if len(name) > 120:
            raise EnrolmentError(Text("a name is at most 120 characters"))
        enrolled.real_name = name or None

    def trials(self, enrolled: StudyParticipant) -> list[Trial]:
        """The participant's trials in this study, oldest first."""
        pid = enrolled.participant_id
        return list(
            self.db.scalars(
                select(Trial)
                .where(Trial.study == self.config.name, or_(Trial.commander_id == pid, Trial.driver_id == pid))
                .order_by(Trial.id)
            )
        )

    def unplayed(self, trials: list[Trial]) -> set[int]:
        """Of `trials`, those a seat was never opened in (aborted before anyone played)."""
        return set(never_joined(self.db, [t.id for t in trials]))

    def _own(self, enrolled: StudyParticipant, trial_id: int) -> Trial:
        trial = self.db.get(Trial, trial_id)
        if trial is None or trial not in self.trials(enrolled):
            raise EnrolmentError(Text("trial {trial} is not one of yours in this study", trial=trial_id))
        return trial

    def after(self, enrolled: StudyParticipant, trial_id: int) -> AfterTrial:
        trial = self._own(enrolled, trial_id)
        if trial.phase not in ("finished", "aborted"):
            return AfterTrial.study_page
        if trial.excluded_reason == PRACTICE_REASON or self.unplayed([trial]):
            return AfterTrial.lobby
        if trial_id in self.answered(enrolled) or enrolled.withdrawn_at is not None:
            return AfterTrial.study_page
        return AfterTrial.questionnaire

    def answered(self, enrolled: StudyParticipant) -> set[int]:
        return set(self.db.scalars(select(StudyAnswer.trial_id).where(StudyAnswer.study_participant_id == enrolled.id)))

    def questionnaire_due(self, enrolled: StudyParticipant, trial_id: int) -> None:
        """Whether the questionnaire after `trial_id` may be shown and answered: a trial of the
        participant's, played and over, not the practice, not answered yet; else `EnrolmentError`."""
        self._active(enrolled)
        trial = self._own(enrolled, trial_id)
        if trial.excluded_reason == PRACTICE_REASON:
            raise EnrolmentError(Text("the practice trial has no questionnaire"))
        if trial.phase not in ("finished", "aborted"):
            raise EnrolmentError(Text("the questionnaire opens when the trial is over"))
        if self.unplayed([trial]):
            raise EnrolmentError(Text("this trial never started (a seat was never opened): it has no questionnaire"))
        if trial_id in self.answered(enrolled):
            raise EnrolmentError(Text("you have already answered the questionnaire for this trial"))

    def answer(self, enrolled: StudyParticipant, trial_id: int, form: dict[str, str]) -> None:
        """The questionnaire after `trial_id`: every rating item answered 1-5, free text optional."""
        self.questionnaire_due(enrolled, trial_id)
        ratings: dict[str, int] = {}
        free_text: dict[str, str] = {}
        for q in self.config.questionnaire:
            value = form.get(q.id, "").strip()
            if q.kind is QuestionKind.free_text:
                if len(value) > MAX_FREE_TEXT:
                    raise EnrolmentError(
                        Text("'{prompt}' takes at most {n} characters", prompt=q.prompt, n=MAX_FREE_TEXT)
                    )
                if value:
                    free_text[q.id] = value
                continue
            low, high = RATING_SCALE
            if not value.isdigit() or not low <= int(value) <= high:
                raise EnrolmentError(
                    Text("'{prompt}' needs a rating from {low} to {high}", prompt=q.prompt, low=low, high=high)
                )
            ratings[q.id] = int(value)
        self.db.add(
            StudyAnswer(
                study_participant_id=enrolled.id, trial_id=trial_id, ratings=ratings, free_text=free_text or None
            )
        )
        # The log keeps the ratings (pseudonymous) and never the free text (erasable personal data).
        self._log(StudyEventKind.answered, enrolled.participant_id, trial_id=trial_id, ratings=ratings)

    def outcome(self, enrolled: StudyParticipant) -> StudyOutcome | None:
        """How the participant's way ended, where it has: the end recorded first (a withdrawal
        after it keeps it), else `withdrew` for a withdrawal."""
        ended = self.db.scalars(
            select(StudyEvent.payload)
            .where(
                StudyEvent.study == self.config.name,
                StudyEvent.participant_id == enrolled.participant_id,
                StudyEvent.kind == StudyEventKind.completed,
            )
            .order_by(StudyEvent.id)
        ).first()
        if ended is not None:
            return StudyOutcome(ended.get("outcome", StudyOutcome.completed))  # older logs: the plan
        return StudyOutcome.withdrew if enrolled.withdrawn_at is not None else None

    def end(self, enrolled: StudyParticipant, outcome: StudyOutcome, trials: int) -> StudyOutcome:
        """Record the end of the participant's way (`trials`: study trials played); once: a second
        end keeps the first. The code is theirs once the caller has committed this."""
        ended = self.outcome(enrolled)
        if ended is not None:
            return ended
        self._active(enrolled)
        enrolled.completed_at = datetime.now(UTC)
        end_wait(enrolled, enrolled.completed_at)
        enrolled.lobby_seen = None
        self._log(StudyEventKind.completed, enrolled.participant_id, outcome=str(outcome), trials=trials)
        return outcome

    def withdraw(self, enrolled: StudyParticipant) -> None:
        """Erase the participant's personal data (real name, free text); keep pseudonymous events."""
        if enrolled.withdrawn_at is not None:
            return
        enrolled.real_name = None
        for answer in self.db.scalars(select(StudyAnswer).where(StudyAnswer.study_participant_id == enrolled.id)):
            answer.free_text = None
        enrolled.withdrawn_at = datetime.now(UTC)
        self._log(StudyEventKind.withdrawn, enrolled.participant_id)

    def _active(self, enrolled: StudyParticipant) -> None:
        if enrolled.withdrawn_at is not None:
            raise EnrolmentError(Text("you have withdrawn from this study; nothing more is recorded"))

    def participants(self) -> list[tuple[StudyParticipant, str, int]]:
        """Everyone enrolled: (enrolment, code, questionnaires answered), for the experimenter."""
        rows = self.db.execute(
            select(StudyParticipant, Participant.name)
            .join(Participant, Participant.id == StudyParticipant.participant_id)
            .where(StudyParticipant.study == self.config.name)
            .order_by(StudyParticipant.id)
        ).all()
        return [(e, code, len(self.answered(e))) for e, code in rows]

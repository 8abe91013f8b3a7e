"""The tables. The event log is the truth; `trial`'s phase/score columns are a cache of it
kept for the leaderboard and dashboard, rewritten with each phase change."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from sqlalchemy import JSON, BigInteger, DateTime, Float, ForeignKey, Integer, String, Text, UniqueConstraint
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column

# An event's payload as the JSON column holds it: its shape is the event kind's (sim.trial.events).
JsonObject = dict[str, Any]


def utcnow() -> datetime:
    return datetime.now(UTC)


class Base(DeclarativeBase):
    """Every table's row has an integer id, its primary key."""

    id: Mapped[int] = mapped_column(Integer, primary_key=True, sort_order=-1)  # the first column


class Created:
    """When the row was made (the server's wall clock)."""

    created_at: Mapped[datetime] = mapped_column(DateTime(timezone=True), default=utcnow)


class LogEntry:
    """The columns of a row of any of the logs: what happened (its kind), when (the server's
    clock, ns) and the JSON payload its kind defines."""

    kind: Mapped[str] = mapped_column(String(32))
    t_ns: Mapped[int] = mapped_column(BigInteger)
    payload: Mapped[JsonObject] = mapped_column(JSON)


class Experimenter(Created, Base):
    __tablename__ = "experimenter"
    name: Mapped[str] = mapped_column(String(80), unique=True)
    password_hash: Mapped[str] = mapped_column(String(255))
    # Bumped by logout and by a password change: login cookies name the version they were issued at.
    session_version: Mapped[int] = mapped_column(Integer, default=0, server_default="0")
    # app.security.AccountRole: an annotator's login opens only the annotation pages.
    role: Mapped[str] = mapped_column(String(16), default="experimenter", server_default="experimenter")


class Participant(Created, Base):
    __tablename__ = "participant"
    name: Mapped[str] = mapped_column(String(80), unique=True)


class Team(Created, Base):
    __tablename__ = "team"
    name: Mapped[str] = mapped_column(String(80), unique=True)
    member_a_id: Mapped[int] = mapped_column(ForeignKey("participant.id"))
    member_b_id: Mapped[int] = mapped_column(ForeignKey("participant.id"))


class Robot(Created, Base):
    __tablename__ = "robot"
    name: Mapped[str] = mapped_column(String(80), unique=True)
    token_hash: Mapped[str] = mapped_column(String(255))
    role: Mapped[str] = mapped_column(String(16))  # 'driver' (the rover) or 'overhead' (tracker camera)


class Trial(Created, Base):
    __tablename__ = "trial"
    team_id: Mapped[int | None] = mapped_column(ForeignKey("team.id"), nullable=True)  # None: agents in both seats
    maze: Mapped[str] = mapped_column(String(80))
    targets: Mapped[list[str]] = mapped_column(JSON)  # the three objects, in the order to reach them
    backend: Mapped[str] = mapped_column(String(40))  # 'sim' or 'robot:<id>'
    driver: Mapped[str] = mapped_column(String(40))  # 'human' or 'agent:<name>'
    commander: Mapped[str] = mapped_column(String(40), default="human", server_default="human")  # as `driver`
    study: Mapped[str | None] = mapped_column(String(80), nullable=True, index=True)  # the study's name, if any
    commander_id: Mapped[int | None] = mapped_column(ForeignKey("participant.id"), nullable=True)
    driver_id: Mapped[int | None] = mapped_column(ForeignKey("participant.id"), nullable=True)
    # Cache of the event log (see module docstring).
    phase: Mapped[str] = mapped_column(String(16), default="waiting")
    active_s: Mapped[float | None] = mapped_column(Float, nullable=True)  # start to last confirmation
    moves: Mapped[int] = mapped_column(Integer, default=0)
    # Set by the experimenter: the trial leaves the leaderboard and exports; its log is kept.
    excluded_reason: Mapped[str | None] = mapped_column(Text, nullable=True)
    # The experimenter's notes (private: shown on the trial's and replay's pages only).
    notes: Mapped[str | None] = mapped_column(Text, nullable=True)


class Event(LogEntry, Base):
    __tablename__ = "event"
    __table_args__ = (UniqueConstraint("trial_id", "seq", name="uq_event_trial_seq"),)
    trial_id: Mapped[int] = mapped_column(ForeignKey("trial.id"), index=True)
    seq: Mapped[int] = mapped_column(Integer)


class Frame(Base):
    __tablename__ = "frame"
    trial_id: Mapped[int] = mapped_column(ForeignKey("trial.id"), index=True)
    seq: Mapped[int] = mapped_column(Integer)  # the `frame` event's seq
    source: Mapped[str] = mapped_column(String(16))  # 'driver' (robot camera) or 'overhead'
    path: Mapped[str] = mapped_column(Text)  # relative to data_dir/frames
    capture_ns: Mapped[int] = mapped_column(BigInteger)
    width: Mapped[int] = mapped_column(Integer)
    height: Mapped[int] = mapped_column(Integer)


class LDHStudy(Created, Base):
    """A human LDH study: its instances are frozen at creation (`LDHStudyInstance`)."""

    __tablename__ = "ldh_study"
    name: Mapped[str] = mapped_column(String(80))
    source: Mapped[str] = mapped_column(Text)  # the folder in the benchmark's layout it was drawn from
    split: Mapped[str] = mapped_column(String(16))
    variant: Mapped[str] = mapped_column(String(16))  # sim.tasks.ldh.Variant
    language: Mapped[str] = mapped_column(String(8), default="en", server_default="en")  # app.i18n.Language
    experimenter_id: Mapped[int] = mapped_column(ForeignKey("experimenter.id"))


class LDHStudyInstance(Base):
    __tablename__ = "ldh_study_instance"
    __table_args__ = (UniqueConstraint("study_id", "position", name="uq_ldh_instance_position"),)
    study_id: Mapped[int] = mapped_column(ForeignKey("ldh_study.id"), index=True)
    position: Mapped[int] = mapped_column(Integer)  # the order participants see them in, from 0
    inst_idx: Mapped[int] = mapped_column(Integer)
    run: Mapped[str] = mapped_column(String(80))
    dialog: Mapped[list[list[str]]] = mapped_column(JSON)  # [[role, message], ...]
    true_x: Mapped[float] = mapped_column(Float)
    true_y: Mapped[float] = mapped_column(Float)
    true_heading: Mapped[float | None] = mapped_column(Float, nullable=True)


class LDHStudyParticipant(Created, Base):
    __tablename__ = "ldh_study_participant"
    __table_args__ = (UniqueConstraint("study_id", "name", name="uq_ldh_participant_name"),)
    study_id: Mapped[int] = mapped_column(ForeignKey("ldh_study.id"), index=True)
    name: Mapped[str] = mapped_column(String(80))


class LDHStudyEvent(LogEntry, Base):
    """A study's log: every answer, committed before the participant hears it was taken."""

    __tablename__ = "ldh_study_event"
    __table_args__ = (UniqueConstraint("study_id", "seq", name="uq_ldh_event_study_seq"),)
    study_id: Mapped[int] = mapped_column(ForeignKey("ldh_study.id"), index=True)
    seq: Mapped[int] = mapped_column(Integer)


class AnnotationEvent(LogEntry, Base):
    """The annotations' own log (app.annotation.events): who annotated which trial, when, and
    what; a later event of the same annotator, kind and key revises the one it names."""

    __tablename__ = "annotation_event"
    trial_id: Mapped[int] = mapped_column(ForeignKey("trial.id"), index=True)
    annotator_id: Mapped[int] = mapped_column(ForeignKey("experimenter.id"))
    revises: Mapped[int | None] = mapped_column(Integer, nullable=True)  # the id of the event it replaces


class AnnotationAssignment(Created, Base):
    """A trial in an annotator's queue (two rows for a trial sampled for double annotation)."""

    __tablename__ = "annotation_assignment"
    __table_args__ = (UniqueConstraint("trial_id", "annotator_id", name="uq_assignment_trial_annotator"),)
    trial_id: Mapped[int] = mapped_column(ForeignKey("trial.id"), index=True)
    annotator_id: Mapped[int] = mapped_column(ForeignKey("experimenter.id"), index=True)


class StudyParticipant(Created, Base):
    """A participant of a study (`app.study`): the `Participant` row's public name is their code;
    the real name is optional, private (experimenter's pages only) and erased on withdrawal."""

    __tablename__ = "study_participant"
    study: Mapped[str] = mapped_column(String(80), index=True)
    participant_id: Mapped[int] = mapped_column(ForeignKey("participant.id"), unique=True)
    real_name: Mapped[str | None] = mapped_column(String(120), nullable=True)
    consent_version: Mapped[str] = mapped_column(String(40))
    completed_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)
    withdrawn_at: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)
    # The lobby (`app.study.lobby`): waiting since, and the last time the lobby page asked.
    lobby_since: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)
    lobby_seen: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)
    # Seconds waited in the lobby over every wait that has ended (for paying waiting time).
    lobby_waited_s: Mapped[float] = mapped_column(Float, default=0.0, server_default="0")
    lobby_waited_to: Mapped[datetime | None] = mapped_column(DateTime(timezone=True), nullable=True)  # counted so far
    # The recruiting panel's identifiers from the study link (`StudyConfig.panel`): personal data,
    # on no public page; kept through a withdrawal (the panel pays by them) until the study's purge.
    panel_participant: Mapped[str | None] = mapped_column(String(200), nullable=True)
    panel_study: Mapped[str | None] = mapped_column(String(200), nullable=True)
    panel_session: Mapped[str | None] = mapped_column(String(200), nullable=True)


class StudyEvent(LogEntry, Base):
    """A study's pseudonymous log (consent with the text's version, declines, answers, withdrawal):
    kept when a participant withdraws. Its kinds: `app.study.enrolment.StudyEventKind`."""

    __tablename__ = "study_event"
    study: Mapped[str] = mapped_column(String(80), index=True)
    participant_id: Mapped[int | None] = mapped_column(ForeignKey("participant.id"), nullable=True)  # None: declined


class StudyAnswer(Created, Base):
    """One questionnaire after one trial. Ratings are pseudonymous; free text is personal data and
    is erased (set to None) when the participant withdraws."""

    __tablename__ = "study_answer"
    __table_args__ = (UniqueConstraint("study_participant_id", "trial_id", name="uq_study_answer_trial"),)
    study_participant_id: Mapped[int] = mapped_column(ForeignKey("study_participant.id"), index=True)
    trial_id: Mapped[int] = mapped_column(ForeignKey("trial.id"))
    ratings: Mapped[dict[str, int]] = mapped_column(JSON)  # question id -> 1..5
    free_text: Mapped[dict[str, str] | None] = mapped_column(JSON, nullable=True)  # question id -> text

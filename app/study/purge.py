"""Deleting a study's personal data a set time after it closes (`StudyConfig.purge_after_days`
after `closed_at`): every participant's real name and panel identifiers and every free-text answer
are set to null; the codes, ratings, trials and the pseudonymous log stay. Run by `robotslang study
purge` and at each server start; a purge that deleted something is logged (`purged`)."""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.clock import ServerClock
from app.db.models import StudyAnswer, StudyEvent, StudyParticipant
from app.study.config import StudyConfig, StudyConfigError, StudyFiles
from app.study.enrolment import StudyEventKind


def purge(db: Session, config: StudyConfig, clock: ServerClock) -> int:
    """Delete the study's personal data now; how many participants had some."""
    people = db.scalars(select(StudyParticipant).where(StudyParticipant.study == config.name)).all()
    had = 0
    for enrolled in people:
        # Read in Python: a JSON column's null may be stored as JSON's null, not SQL's NULL.
        answers = db.scalars(select(StudyAnswer).where(StudyAnswer.study_participant_id == enrolled.id)).all()
        fields = (enrolled.real_name, enrolled.panel_participant, enrolled.panel_study, enrolled.panel_session)
        if any(f is not None for f in fields) or any(a.free_text for a in answers):
            had += 1
        enrolled.real_name = enrolled.panel_participant = enrolled.panel_study = enrolled.panel_session = None
        for answer in answers:
            answer.free_text = None
    if had:
        db.add(
            StudyEvent(
                study=config.name,
                participant_id=None,
                kind=StudyEventKind.purged,
                t_ns=clock.now_ns(),
                payload={"study_version": config.version, "participants": had},
            )
        )
    return had


def purge_due(
    db: Session, files: StudyFiles, clock: ServerClock, now: datetime, names: list[str] | None = None
) -> dict[str, int]:
    """Purge every study (of `names`) whose time has come: study name -> participants whose data
    were deleted (a study file that does not validate is skipped: its page says why)."""
    purged: dict[str, int] = {}
    for name in files.names() if names is None else names:
        try:
            config = files.load(name)
        except (LookupError, StudyConfigError):
            continue
        if config.purge_due(now):
            purged[name] = purge(db, config, clock)
    return purged

"""Trials from the database as `TrialRecord`s: the one place exports touch the tables."""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.annotation.log import AnnotationLog
from app.db.models import Event as EventRow
from app.db.models import Team, Trial
from app.export.record import ExportError, TrialRecord
from app.settings import Settings
from sim.trial.state import LoggedEvent
from sim.trial.vocabulary import Phase


def load_trial(session: Session, settings: Settings, trial_id: int | str) -> TrialRecord:
    """The trial's row and its whole event log, in `seq` order."""
    try:
        key = int(trial_id)
    except ValueError:
        raise ExportError(f"trial id {trial_id!r} is not a number") from None
    trial = session.get(Trial, key)
    if trial is None:
        raise ExportError(f"no trial {key} in {settings.url.split('@')[-1]}")
    team = session.get(Team, trial.team_id) if trial.team_id is not None else None  # None: an agent pair
    rows = session.scalars(select(EventRow).where(EventRow.trial_id == key).order_by(EventRow.seq))
    events = tuple(LoggedEvent(seq=r.seq, kind=r.kind, t_ns=r.t_ns, payload=dict(r.payload)) for r in rows)
    annotations = AnnotationLog.fold_in(session, key)
    return TrialRecord(
        localized_after=annotations.resolved_cut(),
        tags=annotations.resolved_tags(),
        trial_id=str(key),
        team=team.name if team else "",
        maze=trial.maze,
        targets=tuple(trial.targets),
        events=events,
        frames_root=settings.frames_dir,
        info={
            "backend": trial.backend,
            "driver": trial.driver,
            "phase": trial.phase,
            # Seats by participant id (a pseudonym: names stay in the database).
            "commander": f"participant {trial.commander_id}" if trial.commander_id is not None else trial.commander,
            "driver_seat": f"participant {trial.driver_id}" if trial.driver_id is not None else trial.driver,
            **({"excluded": trial.excluded_reason} if trial.excluded_reason is not None else {}),
            "created_at": trial.created_at.isoformat() if trial.created_at else "",
        },
    )


def exported_trial_ids(session: Session, include_aborted: bool = False, study: str | None = None) -> list[int]:
    """What `export all` writes: every finished trial (and aborted ones, with what they recorded,
    when asked), never one the experimenter excluded; with `study`, only that study's."""
    phases = [Phase.FINISHED, Phase.ABORTED] if include_aborted else [Phase.FINISHED]
    query = select(Trial.id).where(Trial.phase.in_(phases), Trial.excluded_reason.is_(None))
    if study is not None:
        query = query.where(Trial.study == study)
    return list(session.scalars(query.order_by(Trial.id)))

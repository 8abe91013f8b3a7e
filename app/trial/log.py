"""`EventLog`: the one place events are written. An event is committed before anyone hears of it."""

from __future__ import annotations

from typing import Any

from sqlalchemy import insert, select, update
from sqlalchemy.orm import sessionmaker

from app.db import models
from app.trial.state import LoggedEvent


class EventLog:
    def __init__(self, sessions: sessionmaker) -> None:
        self.sessions = sessions
        self.engine = sessions.kw["bind"]

    def load(self, trial_id: int) -> list[LoggedEvent]:
        with self.sessions() as db:
            rows = db.scalars(select(models.Event).where(models.Event.trial_id == trial_id)
                              .order_by(models.Event.seq))
            return [LoggedEvent(r.seq, r.kind, r.t_ns, r.payload) for r in rows]

    def append(self, trial_id: int, event: LoggedEvent, *, frame: dict[str, Any] | None = None,
               trial_cache: dict[str, Any] | None = None) -> None:
        """Commit one event, with its frame row and the trial's cached columns in the same
        transaction; raises (and writes nothing) if the seq is already taken."""
        # Core statements, not the ORM: this runs for every event of every live trial.
        with self.engine.begin() as conn:
            conn.execute(insert(models.Event), {"trial_id": trial_id, "seq": event.seq, "kind": event.kind,
                                                "t_ns": event.t_ns, "payload": event.payload})
            if frame is not None:
                conn.execute(insert(models.Frame), {"trial_id": trial_id, "seq": event.seq, **frame})
            if trial_cache:
                conn.execute(update(models.Trial).where(models.Trial.id == trial_id).values(**trial_cache))

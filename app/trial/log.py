"""`EventLog`: the one place events are written. An event is committed before anyone hears of it.

Group commit: the events appended during one turn of the event loop (every trial of the
process) are committed in one transaction at the end of that turn, and what the seats are to
hear of them (`after_commit`) is sent only once that transaction has committed, in order. One
commit per turn instead of one per event is what lets one process carry hundreds of trials.
Without a running loop (scripts, tests), each append commits at once.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable
from typing import Any

from sqlalchemy import insert, select, update
from sqlalchemy.orm import Session, sessionmaker

from app.db import models
from app.trial.state import LoggedEvent

logger = logging.getLogger(__name__)


class EventLog:
    def __init__(self, sessions: sessionmaker[Session]) -> None:
        self.sessions = sessions
        self.engine = sessions.kw["bind"]
        self._events: list[dict[str, Any]] = []
        self._frames: list[dict[str, Any]] = []
        self._caches: dict[int, dict[str, Any]] = {}
        self._after: list[tuple[int, Callable[..., None], tuple[Any, ...]]] = []
        self._scheduled = False
        self._loop: asyncio.AbstractEventLoop | None = None  # the loop whose turns batch the commits
        self.on_lost: Callable[[int, Exception], None] | None = None  # the hub drops a trial whose batch failed

    def load(self, trial_id: int) -> list[LoggedEvent]:
        self.flush()  # read what this process has appended
        with self.sessions() as db:
            rows = db.scalars(select(models.Event).where(models.Event.trial_id == trial_id).order_by(models.Event.seq))
            return [LoggedEvent(r.seq, r.kind, r.t_ns, r.payload) for r in rows]

    def append(
        self,
        trial_id: int,
        event: LoggedEvent,
        *,
        frame: dict[str, Any] | None = None,
        trial_cache: dict[str, Any] | None = None,
    ) -> None:
        """Queue one event, with its frame row and the trial's cached columns, for this turn's
        commit; a seq already taken (another process wrote this trial) fails that trial's part."""
        self._events.append(
            {"trial_id": trial_id, "seq": event.seq, "kind": event.kind, "t_ns": event.t_ns, "payload": event.payload}
        )
        if frame is not None:
            self._frames.append({"trial_id": trial_id, "seq": event.seq, **frame})
        if trial_cache:
            self._caches.setdefault(trial_id, {}).update(trial_cache)
        if self._scheduled:
            return
        try:
            loop = asyncio.get_running_loop()
        except RuntimeError:
            self.flush()
            return
        self._scheduled, self._loop = True, loop
        loop.call_soon(self.flush)

    def after_commit(self, trial_id: int, send: Callable[..., None], *args: Any) -> None:
        """Call `send(*args)` once everything appended so far is committed (now, if it is)."""
        if self._events:
            self._after.append((trial_id, send, args))
        else:
            send(*args)

    def flush(self) -> None:
        """Commit what is queued, then send what waited for it. Only on the loop that queued it:
        another thread (a test, a script reading the log) sees what is committed."""
        if not self._events or (self._scheduled and _running_loop() is not self._loop):
            return
        self._scheduled = False
        events, frames, caches, after = self._events, self._frames, self._caches, self._after
        self._events, self._frames, self._caches, self._after = [], [], {}, []
        lost: set[int] = set()
        try:
            self._write(events, frames, caches)
        except Exception:  # one trial's conflict must not cost the others their events
            for trial_id in dict.fromkeys(e["trial_id"] for e in events):
                try:
                    self._write(
                        [e for e in events if e["trial_id"] == trial_id],
                        [f for f in frames if f["trial_id"] == trial_id],
                        {trial_id: caches[trial_id]} if trial_id in caches else {},
                    )
                except Exception as err:
                    logger.exception("trial %s: events not committed", trial_id)
                    lost.add(trial_id)
                    if self.on_lost is not None:
                        self.on_lost(trial_id, err)
        for trial_id, send, args in after:
            if trial_id not in lost:
                send(*args)

    def _write(
        self, events: list[dict[str, Any]], frames: list[dict[str, Any]], caches: dict[int, dict[str, Any]]
    ) -> None:
        # Core statements, not the ORM: this runs for every event of every live trial.
        with self.engine.begin() as conn:
            conn.execute(insert(models.Event), events)
            if frames:
                conn.execute(insert(models.Frame), frames)
            for trial_id, values in caches.items():
                conn.execute(update(models.Trial).where(models.Trial.id == trial_id).values(**values))


def _running_loop() -> asyncio.AbstractEventLoop | None:
    try:
        return asyncio.get_running_loop()
    except RuntimeError:
        return None

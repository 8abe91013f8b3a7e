"""`EventLog`: the one place events are written. An event is committed before anyone hears of it.

Group commit: the events appended during one turn of the event loop (every trial of the
process) are committed in one transaction, and what the seats are to hear of them
(`after_commit`) is sent only once that transaction has committed, in order. One commit per turn
instead of one per event is what lets one process carry hundreds of trials.

Where the commit runs depends on what it waits for. On PostgreSQL a commit is a round trip and
the server's fsync, so batches go to the log's one writer thread (psycopg waits without the
GIL) and the loop goes on meanwhile; the events appended while one batch commits form the next,
and batches commit one at a time, in order. On SQLite (WAL, synchronous NORMAL: no fsync at a
commit) the commit is a fraction of a millisecond of work and runs on the loop at the end of the
turn: the hop to a thread cost more than it saved (`bench.load`, docs/platform.md). Without a
running loop (scripts, tests), each append commits at once.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any, TypedDict

from sqlalchemy import insert, select, update
from sqlalchemy.orm import Session, sessionmaker

from app.db import models
from sim.trial.state import LoggedEvent

logger = logging.getLogger(__name__)

# (trial id, send, its arguments); no trial id: sent once the commit is done, whatever became of any trial's part
Send = tuple[int | None, Callable[..., None], tuple[Any, ...]]


class EventRow(TypedDict):
    trial_id: int
    seq: int
    kind: str
    t_ns: int
    payload: dict[str, Any]


class FrameRow(TypedDict):
    """A camera image's row beside its `frame` event (the trial and seq are the event's)."""

    source: str
    path: str
    capture_ns: int
    width: int
    height: int


class FrameRecord(FrameRow):
    trial_id: int
    seq: int


class TrialCache(TypedDict):
    """The trial row's columns kept from its log, as a phase changes."""

    phase: str
    moves: int
    active_s: float | None


@dataclass
class _Batch:
    events: list[EventRow] = field(default_factory=list)
    frames: list[FrameRecord] = field(default_factory=list)
    caches: dict[int, TrialCache] = field(default_factory=dict)
    after: list[Send] = field(default_factory=list)


class EventLog:
    def __init__(self, sessions: sessionmaker[Session], writer_thread: bool | None = None) -> None:
        self.sessions = sessions
        self.engine = sessions.kw["bind"]
        # None: a writer thread unless the database is SQLite (see the module's docstring)
        self.writer_thread = self.engine.dialect.name != "sqlite" if writer_thread is None else writer_thread
        self._pending = _Batch()  # appended, not yet handed to the writer
        self._inflight: tuple[Future[dict[int, Exception]], _Batch] | None = None
        self._writer: ThreadPoolExecutor | None = None  # started by the first append on a loop
        self._kicked = False
        self._loop: asyncio.AbstractEventLoop | None = None  # the loop that appends and sends
        self._loop_thread: int | None = None
        self.on_lost: Callable[[int, Exception], None] | None = None  # the hub drops a trial whose batch failed

    def load(self, trial_id: int) -> list[LoggedEvent]:
        if self._holds(trial_id):
            self.flush()  # read what this process has appended to it
        with self.sessions() as db:
            rows = db.scalars(select(models.Event).where(models.Event.trial_id == trial_id).order_by(models.Event.seq))
            return [LoggedEvent(r.seq, r.kind, r.t_ns, r.payload) for r in rows]

    def exists(self, trial_id: int) -> bool:
        """Whether the trial has a log (every trial's begins with `trial_created`): one indexed row,
        where `load` reads them all."""
        if self._holds(trial_id):
            return True
        with self.sessions() as db:
            first = select(models.Event.seq).where(models.Event.trial_id == trial_id).limit(1)
            return db.scalars(first).first() is not None

    def append(
        self,
        trial_id: int,
        event: LoggedEvent,
        *,
        frame: FrameRow | None = None,
        trial_cache: TrialCache | None = None,
    ) -> None:
        """Queue one event, with its frame row and the trial's cached columns, for the next
        commit; a seq already taken (another process wrote this trial) fails that trial's part."""
        batch = self._pending
        batch.events.append(
            EventRow(trial_id=trial_id, seq=event.seq, kind=event.kind, t_ns=event.t_ns, payload=event.payload)
        )
        if frame is not None:
            batch.frames.append(FrameRecord(trial_id=trial_id, seq=event.seq, **frame))
        if trial_cache:
            batch.caches[trial_id] = trial_cache  # the latest phase's
        loop = _running_loop()
        if loop is None:
            self.flush()
            return
        self._loop, self._loop_thread = loop, threading.get_ident()
        if not self._kicked and self._inflight is None:
            self._kicked = True
            loop.call_soon(self._kick)  # at the end of this turn: the turn's events are one batch

    def after_commit(self, trial_id: int | None, send: Callable[..., None], *args: Any) -> None:
        """Call `send(*args)` once everything appended so far is committed (now, if it is)."""
        if self._pending.events or self._pending.after or self._inflight is not None:
            self._pending.after.append((trial_id, send, args))
        else:
            send(*args)

    async def settled(self) -> None:
        """Once everything appended so far has been through a commit: an HTTP answer that reports
        a change (the experimenter's abort) comes only when a reader of the database sees it."""
        done: asyncio.Future[None] = asyncio.get_running_loop().create_future()

        def settle() -> None:
            if not done.done():  # a request cancelled meanwhile (its client went away) cancelled it
                done.set_result(None)

        self.after_commit(None, settle)
        await done

    def flush(self) -> None:
        """Commit everything appended so far and send what waited for it, before returning. On the
        thread of the loop that appends (a reader that must see this turn's events, the server's
        shutdown); on another thread (a test, a script reading the log) it does nothing: that
        reader sees what is committed."""
        if self._loop_thread is not None and threading.get_ident() != self._loop_thread:
            return
        while self._inflight is not None or self._pending.events:
            if self._inflight is not None:
                future = self._inflight[0]
                future.result()  # wait for the writer
                self._committed(future, submit_next=False)
            else:
                batch, self._pending = self._pending, _Batch()
                self._deliver(batch, self._commit(batch))  # waiting anyway: commit here
        self._deliver_waiting()

    def _holds(self, trial_id: int) -> bool:
        """Whether events of this trial wait for (or are in) a commit. Only then must a read of it
        commit first: a crowd of trials opening at once read their logs four times each, and
        committing every other trial's events at each read was a synchronous commit per read."""
        batches = (self._pending, self._inflight[1]) if self._inflight is not None else (self._pending,)
        return any(e["trial_id"] == trial_id for batch in batches for e in batch.events)

    def close(self) -> None:
        """Commit what is queued and stop the writer (the server's shutdown)."""
        self.flush()
        if self._writer is not None:
            self._writer.shutdown()
            self._writer = None

    def _kick(self) -> None:
        self._kicked = False
        if self._inflight is not None or not self._pending.events:
            return
        if self.writer_thread:
            self._submit()
        else:
            batch, self._pending = self._pending, _Batch()
            self._deliver(batch, self._commit(batch))

    def _submit(self) -> None:
        batch, self._pending = self._pending, _Batch()
        if self._writer is None:
            self._writer = ThreadPoolExecutor(1, thread_name_prefix="event-log")
        future = self._writer.submit(self._commit, batch)
        self._inflight = (future, batch)
        loop = self._loop
        assert loop is not None

        def committed(f: Future[dict[int, Exception]]) -> None:
            with contextlib.suppress(RuntimeError):  # the loop closed: its shutdown flushed already
                loop.call_soon_threadsafe(self._committed, f)

        future.add_done_callback(committed)

    def _committed(self, future: Future[dict[int, Exception]], submit_next: bool = True) -> None:
        """On the loop: the writer committed a batch; tell the seats, hand it the next one."""
        if self._inflight is None or self._inflight[0] is not future:
            return  # a synchronous flush handled it already
        batch, self._inflight = self._inflight[1], None
        self._deliver(batch, future.result())
        if not submit_next:
            return
        if self._pending.events:
            self._submit()
        else:
            self._deliver_waiting()

    def _deliver_waiting(self) -> None:
        """Send what waited only for batches already committed (no event was appended after it)."""
        after, self._pending.after = self._pending.after, []
        self._deliver(_Batch(after=after), {})

    def _deliver(self, batch: _Batch, lost: dict[int, Exception]) -> None:
        for trial_id, err in lost.items():
            if self.on_lost is not None:
                self.on_lost(trial_id, err)
        for of_trial, send, args in batch.after:
            if of_trial not in lost:
                send(*args)

    def _commit(self, batch: _Batch) -> dict[int, Exception]:
        """Write one batch; returns the trials whose part could not be committed."""
        lost: dict[int, Exception] = {}
        try:
            self._write(batch.events, batch.frames, batch.caches)
        except Exception:  # one trial's conflict must not cost the others their events
            for trial_id in dict.fromkeys(e["trial_id"] for e in batch.events):
                try:
                    self._write(
                        [e for e in batch.events if e["trial_id"] == trial_id],
                        [f for f in batch.frames if f["trial_id"] == trial_id],
                        {trial_id: batch.caches[trial_id]} if trial_id in batch.caches else {},
                    )
                except Exception as err:
                    logger.exception("trial %s: events not committed", trial_id)
                    lost[trial_id] = err
        return lost

    def _write(self, events: list[EventRow], frames: list[FrameRecord], caches: dict[int, TrialCache]) -> None:
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

"""`RobotSeat`: the robot seat of one live trial: the backend in it (the simulator or a rover), the
frames it streams (stored off the event loop, then logged), the poses it reports, and each move
carried out to its outcome. It records through the trial (`Recording`) and decides nothing."""

from __future__ import annotations

import asyncio
import base64
import logging
from collections.abc import Coroutine
from typing import Any, Protocol

from app.backends.base import BackendUnavailable, Frame, RobotBackend
from app.backends.registry import BackendParts, create_backend
from app.clock import ServerClock
from app.trial.audience import Attachments
from app.trial.frames_store import FrameStore
from app.trial.log import FrameRow
from app.trial.port import RobotTrial
from app.trial.watch import Watch
from sim.core.geometry import wrap_angle
from sim.trial import commands as c
from sim.trial import events as ev
from sim.trial.vocabulary import FrameSource, Move, Outcome, PoseSource, Role

logger = logging.getLogger(__name__)


class Recording(RobotTrial, Protocol):
    def apply(
        self, command: c.Command, attachments: Attachments | None = None, frame: FrameRow | None = None
    ) -> Any: ...

    def spawn(self, coro: Coroutine[Any, Any, Any]) -> asyncio.Task[Any]: ...


class RobotSeat:
    def __init__(self, trial: Recording, frames: FrameStore, clock: ServerClock, watching: Watch) -> None:
        self.trial, self.frames, self.clock, self.watching = trial, frames, clock, watching
        self.backend: RobotBackend | None = None

    async def start(self, parts: BackendParts) -> None:
        self.backend = backend = await create_backend(self.trial.state.backend, self.trial, parts)
        pose = backend.pose()
        if pose is not None and self.trial.state.pose is None:
            self.record_pose(pose)
        self.trial.spawn(self._pump(backend))
        self.watching.want()
        await backend.connect()

    async def close(self) -> None:
        if self.backend is not None:
            backend, self.backend = self.backend, None
            await backend.close()

    async def execute(self, move: Move) -> tuple[Outcome, str | None]:
        """A move the trial has asked for, to its outcome (the referee refuses moves without a backend)."""
        assert self.backend is not None
        started_ns = self.clock.now_ns()
        try:
            result = await self.backend.execute(move)
            outcome, reason = result.outcome, result.reason
        except BackendUnavailable as err:
            outcome, reason = Outcome.REFUSED, str(err)
        if outcome != Outcome.REFUSED:  # a collision on the simulator leaves the robot where it was
            self.watching.moved(move if outcome == Outcome.OK else None, started_ns)
        return outcome, reason

    def moved(self) -> None:
        """A move is over: a simulator knows where it left the robot (a rover's tracker reports its own)."""
        backend = self.backend
        if backend is not None and backend.pose_source == PoseSource.SIM and not self.trial.state.over:
            self.record_pose(backend.pose())

    def true_pose(self) -> tuple[float, float, float] | None:
        return self.backend.pose() if self.backend is not None else None

    def record_pose(self, pose: tuple[float, float, float] | None) -> None:
        if pose is None:
            return
        x, y, theta = pose
        source = self.backend.pose_source if self.backend is not None else PoseSource.TRACKER
        self.trial.apply(c.Note(ev.PoseSampled(x=x, y=y, heading=wrap_angle(theta), source=source)))

    def record_frame(self, frame: Frame, source: FrameSource) -> int:
        rel = FrameStore.name(self.trial.trial_id, frame.capture_ns, source)
        self.frames.write(rel, frame.jpeg)
        return self._log_frame(rel, frame, source)

    async def _pump(self, backend: RobotBackend) -> None:
        async for frame in backend.frames():
            try:
                rel = FrameStore.name(self.trial.trial_id, frame.capture_ns, FrameSource.DRIVER)
                # The file is written off the event loop (slow disks must not delay other trials).
                await asyncio.to_thread(self.frames.write, rel, frame.jpeg)
                self._log_frame(rel, frame, FrameSource.DRIVER)
            except Exception:  # a frame that cannot be stored must not stop the stream
                logger.exception("trial %s: frame not recorded", self.trial.trial_id)
                continue
            self.watching.frame(frame)

    def _log_frame(self, rel: str, frame: Frame, source: FrameSource) -> int:
        frame_id = self.trial.state.last_seq + 1  # the frame event's own seq
        driver = source == FrameSource.DRIVER
        event = ev.FrameRecorded(
            frame_id=frame_id,
            source=source,
            path=rel,
            capture_ns=frame.capture_ns,
            width=frame.width,
            height=frame.height,
            rays=frame.observation if driver else None,  # what the agent seats see of it
            jpeg=frame.jpeg if driver else None,
        )
        row = FrameRow(
            source=str(source), path=rel, capture_ns=frame.capture_ns, width=frame.width, height=frame.height
        )
        attach: Attachments = {Role.DRIVER: {"jpeg": base64.b64encode(frame.jpeg).decode()}} if driver else {}
        self.trial.apply(c.Note(event), attach, frame=row)
        return frame_id

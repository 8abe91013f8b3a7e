"""`TrialBelief`: a live particle filter for one trial whose Driver camera is known.

Each executed move is the filter's odometry; the first Driver frame captured after it (and the
trial's first frame) weighs the particles: a rover's through `sim.robot.perception.perceive`, a
simulator's by the simulator's own ray observation at the frame's pose (`Frame.observation`:
its frames are ideal renders, so perceiving their pixels would cost four times the update and
say nothing more). The belief cloud is shown to the experimenter only (`message()`), never to
a participant.

The event loop only notes moves and keeps the frame to take in (`moved`, `offer`); the particles
are touched by one `FilterWorker` thread per process, which folds in every move noted since
its last turn and weighs by the newest frame kept, so a trial that falls behind skips the
frames in between rather than queueing them.
"""

from __future__ import annotations

import asyncio
import logging
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np

from app.trial.messages import ServerMessage
from sim.core.dynamics import Action
from sim.core.maze import Maze
from sim.core.rays import RayObservation
from sim.robot.camera import CameraCalibration
from sim.robot.frames import FrameError, decode_jpeg
from sim.robot.localization import Belief, ParticleFilter
from sim.robot.perception import PerceptionError, perceive
from sim.trial.vocabulary import Move

logger = logging.getLogger(__name__)

CLOUD_POINTS = 150  # points of the cloud sent to the experimenter's page
PARTICLES, CONVERGED_PARTICLES = 1500, 300  # a cloud within 5 cm needs few (ParticleFilter)
FILTER_SHARE = 0.25  # of one core, at most, for all of a process's filters (it holds the GIL too)


@dataclass(frozen=True)
class Observed:
    """The belief after one frame."""

    belief: Belief
    moves: int  # executed moves the belief has folded in


@dataclass(frozen=True)
class _Kept:
    jpeg: bytes
    capture_ns: int
    observation: RayObservation | None  # known without perceiving the pixels (the simulator)


class TrialBelief:
    def __init__(
        self,
        maze: Maze,
        calibration: CameraCalibration,
        n_particles: int = PARTICLES,
        seed: int | None = None,
        converged_particles: int | None = CONVERGED_PARTICLES,
    ) -> None:
        self.calibration = calibration
        self.filter = ParticleFilter(maze, n_particles, seed=seed, converged_particles=converged_particles)
        self._lock = threading.Lock()  # held for bookkeeping only, never while the filter works
        self._filter_lock = threading.Lock()  # one thread at a time in the filter
        self._moves = 0  # executed moves noted
        self._unfolded: list[Action | None] = []  # noted, not yet in the filter
        self._wanted_after_ns: int | None = 0  # a frame captured after this is wanted (None: none)
        self._kept: _Kept | None = None
        self.latest: Observed | None = None

    def moved(self, move: Move | None, started_ns: int) -> None:
        """An executed move (None: one that left the robot where it was); the next frame
        captured after `started_ns` and taken in once the move is over shows where it ended."""
        with self._lock:
            self._unfolded.append(Action.of(move) if move is not None else None)
            self._moves += 1
            self._wanted_after_ns = started_ns
            self._kept = None

    def wants(self, capture_ns: int) -> bool:
        """Whether a frame captured at `capture_ns` is the one to take in next."""
        return self._wanted_after_ns is not None and capture_ns > self._wanted_after_ns

    def offer(self, jpeg: bytes, capture_ns: int, observation: RayObservation | None = None) -> bool:
        """Keep this frame for the filter's next turn if it is wanted (a newer one replaces it)."""
        with self._lock:
            if not self.wants(capture_ns):
                return False
            self._kept = _Kept(jpeg, capture_ns, observation)
            return True

    def step(self) -> Observed | None:
        """Fold in the moves noted and weigh the particles by the frame kept; None for bytes that
        are not an image of this camera (the belief is left as it was, the frame dropped)."""
        with self._filter_lock:
            with self._lock:
                kept, self._kept = self._kept, None
                unfolded, self._unfolded = self._unfolded, []
                moves = self._moves
            for action in unfolded:
                if action is not None:
                    self.filter.move(action)
            if kept is None:
                return None
            obs = kept.observation
            if obs is None:
                try:
                    obs = perceive(decode_jpeg(kept.jpeg), self.calibration)
                except (FrameError, PerceptionError):
                    return None
            self.filter.update(obs)
            observed = Observed(self.filter.belief(CLOUD_POINTS), moves)
            with self._lock:
                self.latest = observed
                if self._moves == moves:  # no move since: this frame shows where the last one ended
                    self._wanted_after_ns = None
            return observed

    def message(self) -> dict[str, Any] | None:
        """The experimenter's belief message: mean (x, y, heading) and the cloud's (x, y, weight)."""
        if self.latest is None:
            return None
        b = self.latest.belief
        return {
            "type": ServerMessage.BELIEF,
            "mean": [round(b.x, 4), round(b.y, 4), round(b.heading, 4)],
            "spread_m": round(b.spread_m, 4),
            "moves": self.latest.moves,
            "points": np.round(b.cloud[:, [0, 1, 3]], 4).tolist(),
        }


class FilterWorker:
    """One turn at a time per process, in a thread of its own: every trial's filter turns run in the order they became due,
    and rests after each so that the filters take at most `share` of a core: under load a
    trial's belief lags (its moves are folded in at its next turn), the moves' frames do not.
    New trials' filters are built in the same share (`start`): a crowd of trials opening at once
    gets its beliefs later, not its frames. The thread is the worker's own, not the event loop's
    default threads: those write every frame to disk, and a turn queued behind them (with its rest
    reckoned from that wait) left most of 100 walking trials without a filter after a minute."""

    def __init__(self, share: float = FILTER_SHARE) -> None:
        self.share = share
        self._due: dict[TrialBelief, Callable[[], None]] = {}  # insertion order: turn order
        self._task: asyncio.Task[None] | None = None
        self._slot: asyncio.Lock | None = None  # one turn or build at a time, with its rest
        self._thread = ThreadPoolExecutor(max_workers=1, thread_name_prefix="particle-filters")

    async def _in_share(self, work: Callable[[], Any]) -> Any:
        """`work()` in the worker's thread; its result at once, and the next work only after a rest
        that keeps the filters' CPU within `share` of a core (a trial's new filter is in use while
        the worker rests)."""
        if self._slot is None:
            self._slot = asyncio.Lock()
        slot = self._slot
        await slot.acquire()
        cpu_s = 0.0

        def timed() -> Any:
            nonlocal cpu_s
            started = time.thread_time()
            try:
                return work()
            finally:
                cpu_s = time.thread_time() - started

        loop = asyncio.get_running_loop()
        try:
            return await loop.run_in_executor(self._thread, timed)
        finally:
            loop.call_later(cpu_s * (1 / self.share - 1), slot.release)

    async def start(self, make: Callable[[], TrialBelief]) -> TrialBelief:
        """A new trial's filter, `make()` in the filters' share of a core."""
        belief: TrialBelief = await self._in_share(make)
        return belief

    def due(self, belief: TrialBelief, done: Callable[[], None]) -> None:
        """`belief` has a frame kept: give it a turn; `done()` runs on the event loop after it."""
        self._due[belief] = done
        if self._task is None or self._task.done():
            self._task = asyncio.get_running_loop().create_task(self._run())

    def forget(self, belief: TrialBelief) -> None:
        self._due.pop(belief, None)

    async def _run(self) -> None:
        while self._due:
            belief = next(iter(self._due))
            done = self._due.pop(belief)
            try:
                observed = await self._in_share(belief.step)
            except Exception:  # a filter that fails is a lesser trial, never a stopped worker
                logger.exception("particle filter turn failed")
                observed = None
            if observed is not None:
                done()

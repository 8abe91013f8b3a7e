"""`Watch`: the experimenter's live views of one trial, and what only they see: the particle
filter's belief on the Driver camera and the LDH model's belief from the dialog. Never a seat's.

The particle filter runs only while someone watches: its belief is for the watch page alone, and
a crowd's unwatched trials would otherwise give it a core and most of the memory. It is built when
the first watcher comes (from a uniform prior and the camera's latest frame) and let go when the
last one leaves.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Coroutine
from dataclasses import dataclass
from typing import Any, Protocol

from app.backends.base import Frame
from app.mazes import Mazes
from app.perception.belief import FilterWorker, TrialBelief
from app.perception.cameras import CameraUnknown, driver_calibration
from app.settings import Settings
from app.trial.ldh_belief import BeliefModel, LiveBelief
from app.trial.messages import Message
from app.trial.port import Connection
from sim.trial.events import LoggedEvent
from sim.trial.state import TrialState
from sim.trial.vocabulary import Move

logger = logging.getLogger(__name__)


class WatchedTrial(Protocol):
    trial_id: int
    history: list[LoggedEvent]

    @property
    def state(self) -> TrialState: ...

    def spawn(self, coro: Coroutine[Any, Any, Any]) -> asyncio.Task[Any]: ...


@dataclass(frozen=True)
class WatchParts:
    settings: Settings
    mazes: Mazes
    filters: FilterWorker  # every trial's particle filter turns
    ldh: BeliefModel


class Watch:
    def __init__(self, trial: WatchedTrial, parts: WatchParts) -> None:
        self.trial, self.parts = trial, parts
        self.watchers: set[Connection] = set()
        self.belief: TrialBelief | None = None
        self.message: Message | None = None  # the filter's latest belief, for the watch page
        self._building: asyncio.Task[None] | None = None
        self._last_frame: Frame | None = None  # the Driver camera's latest, for a filter built after it
        self.ldh = LiveBelief(trial, self.watchers, parts.ldh, parts.mazes)

    def add(self, conn: Connection, live: bool) -> None:
        """A watcher, already welcomed; `live`: the robot is connected (a filter has frames to take)."""
        self.watchers.add(conn)
        self.ldh.welcome(conn)
        if self.message is not None:
            conn.deliver(self.message)
        if live:
            self.want()

    def remove(self, conn: Connection) -> None:
        self.watchers.discard(conn)
        if not self.watchers:
            self.close()

    def want(self) -> None:
        """Build the filter if someone watches and none is built or building."""
        if self.watchers and self.belief is None and self._building is None:
            self._building = self.trial.spawn(self._build())

    def frame(self, frame: Frame) -> None:
        """A Driver frame for the filter, taken in at its next turn (not while a move runs)."""
        self._last_frame = frame
        belief = self.belief
        if (
            belief is not None
            and not self.trial.state.moves_in_flight
            and belief.offer(frame.jpeg, frame.capture_ns, frame.observation)
        ):
            self.parts.filters.due(belief, self._believed)

    def moved(self, move: Move | None, started_ns: int) -> None:
        """An executed move (None: it left the robot where it was)."""
        if self.belief is not None:
            self.belief.moved(move, started_ns)

    def close(self) -> None:
        """Let go of the filter: its particles and free-space map (several MB, and the maze) sit in
        reference cycles with the trial that the collector frees only later."""
        if self._building is not None:
            self._building.cancel()
            self._building = None
        if self.belief is not None:
            belief, self.belief = self.belief, None
            self.parts.filters.forget(belief)
        self.message = None

    async def _build(self) -> None:
        state, settings = self.trial.state, self.parts.settings
        try:
            calibration = await asyncio.to_thread(driver_calibration, state.backend, settings)
            maze = self.parts.mazes.load(state.maze)
            seed = self.trial.trial_id
            self.belief = await self.parts.filters.start(lambda: TrialBelief(maze, calibration, seed=seed))
            # Built in the filters' share of a core, so frames may have come meanwhile: it starts
            # from what the camera sees now (its prior is uniform, so the moves before do not count).
            if self._last_frame is not None:
                self.frame(self._last_frame)
        except CameraUnknown as err:
            logger.info("trial %s: no particle filter: %s", self.trial.trial_id, err)
        except Exception:  # no belief is a lesser trial, not a broken one
            logger.exception("trial %s: no particle filter", self.trial.trial_id)
        finally:
            if self._building is asyncio.current_task():  # not a newer one, after a drop
                self._building = None

    def _believed(self) -> None:
        """The filter has taken in a frame: the watchers see the new belief."""
        if self.belief is None or (message := self.belief.message()) is None:
            return
        self.message = message
        for conn in list(self.watchers):
            conn.deliver(message)

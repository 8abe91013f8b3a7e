"""`TrialBelief`: a live particle filter for one trial whose Driver camera is known.

Each executed move is the filter's odometry; the first Driver frame captured after it (and the
trial's first frame) goes through `sim.perception.perceive` and weighs the particles. The
perceived rays (in `RayTable.features` layout) and the belief are what an agent Driver on a
rover observes in place of the simulator's ray table; the belief cloud is shown to the
experimenter only (`message()`), never to a participant.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from sim.camera import CameraCalibration
from sim.dynamics import Action
from sim.localization import Belief, ParticleFilter
from sim.maze import Maze
from sim.perception import PerceptionError, RayObservation, decode_frame, features, perceive

CLOUD_POINTS = 150  # points of the cloud sent to the experimenter's page


@dataclass(frozen=True)
class Observed:
    """What the camera said at one frame, and the belief after it."""

    frame_capture_ns: int
    rays: np.ndarray  # (OBS_FEATURES,) float32, RayTable.features layout
    observation: RayObservation
    belief: Belief
    moves: int  # executed moves the belief has folded in


class TrialBelief:
    def __init__(
        self, maze: Maze, calibration: CameraCalibration, n_particles: int = 1500, seed: int | None = None
    ) -> None:
        self.calibration = calibration
        self.filter = ParticleFilter(maze, n_particles, seed=seed)
        self._lock = threading.Lock()  # moves come from the event loop, frames from worker threads
        self._moves = 0
        self._wanted_after_ns: int | None = 0  # a frame captured after this is wanted (None: none)
        self.latest: Observed | None = None

    def moved(self, action: str | None, started_ns: int) -> None:
        """An executed move (None: one that left the robot where it was); the next frame
        captured after `started_ns` and taken in once the move is over shows where it ended."""
        with self._lock:
            if action is not None:
                self.filter.move(Action.parse(action))
            self._moves += 1
            self._wanted_after_ns = started_ns

    def wants(self, capture_ns: int) -> bool:
        """Whether a frame captured at `capture_ns` is the one to perceive next."""
        return self._wanted_after_ns is not None and capture_ns > self._wanted_after_ns

    def observe(self, jpeg: bytes, capture_ns: int) -> Observed | None:
        """Perceive one frame and weigh the particles by it; None for bytes that are not an
        image of this camera (the belief is left as it was)."""
        try:
            obs = perceive(decode_frame(jpeg), self.calibration)
        except PerceptionError:
            return None
        with self._lock:
            if not self.wants(capture_ns):
                return self.latest  # another frame got there first
            self.filter.update(obs)
            self._wanted_after_ns = None
            self.latest = Observed(capture_ns, features(obs), obs, self.filter.belief(CLOUD_POINTS), self._moves)
            return self.latest

    @property
    def settled(self) -> bool:
        """The belief has taken in the frame after the last move."""
        return self._wanted_after_ns is None and self.latest is not None

    def message(self) -> dict | None:
        """The experimenter's belief message: mean (x, y, heading) and the cloud's (x, y, weight)."""
        if self.latest is None:
            return None
        b = self.latest.belief
        return {
            "type": "belief",
            "mean": [round(b.x, 4), round(b.y, 4), round(b.heading, 4)],
            "spread_m": round(b.spread_m, 4),
            "moves": self.latest.moves,
            "points": np.round(b.cloud[:, [0, 1, 3]], 4).tolist(),
        }

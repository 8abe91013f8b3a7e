"""The software rover's physics: a continuous pose on a maze, moved by pulses with real errors.

A real rover does not land on the navigation grid: each 0.07 m step is a few millimetres long
or short and bends a little, each 45 degree turn is a degree or two off, and a wall stops it
wherever it touches. `Rover` models that. Its body is a disc; a pose is free while the disc
keeps clear of every wall and landmark object of the maze's `labels` grid and of the table's
edge. A move is planned as a fine path (1 mm or 1 degree per sample) from the sampled error,
swept for the first contact, and then followed for as much of the pulse as ran, so a pulse cut
short by a stop or the watchdog leaves the rover part way. Seeded: the same seed and moves give
the same poses.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from robot_client.protocol import Move
from sim.core.geometry import GRID_STEP_M, TABLE_HEIGHT_M, TABLE_WIDTH_M, TURN_RAD, world_to_pixel
from sim.core.labels import Label
from sim.core.maze import Maze
from sim.core.observations import PX_PER_M_X, WALL_CLEARANCE_M

# The body's radius: the simulator's own clearance (a forward move collides there when it would
# end nearer a wall than 38 map pixels, 0.067 m), so the rover drives as near a wall as the
# simulated agent may. (The grid's square clearance and its dropped diagonals still make the two
# disagree on some moves: the rover is a body on the table, not a walk on the graph.)
BODY_RADIUS_M = WALL_CLEARANCE_M
PATH_STEP_M = 0.001  # forward paths are swept every millimetre
PATH_STEP_RAD = math.radians(1.0)  # turns every degree


@dataclass(frozen=True)
class MotionNoise:
    """Standard deviations of one pulse's error (a range of +- two of them covers 95 %)."""

    forward_m: float = 0.0  # length of a 0.07 m step
    forward_bend_rad: float = 0.0  # heading change over a step (the wheels never match)
    turn_rad: float = 0.0  # angle of a 45 degree turn
    turn_slip_m: float = 0.0  # sideways creep of the centre during a turn, per axis

    @classmethod
    def named(cls, name: str) -> MotionNoise:
        try:
            return NOISE_MODELS[name]
        except KeyError:
            raise ValueError(f"unknown noise model {name!r}; expected one of {', '.join(NOISE_MODELS)}") from None


NOISE_MODELS = {
    # forward 0.07 m +- 4 mm, turns 45 +- 2 degrees, a step bends by +- 1 degree, turns creep +- 2 mm.
    "default": MotionNoise(
        forward_m=0.002, forward_bend_rad=math.radians(0.5), turn_rad=math.radians(1.0), turn_slip_m=0.001
    ),
    "none": MotionNoise(),
}


@dataclass(frozen=True)
class RoverPose:
    x: float  # metres
    y: float
    theta: float  # radians in [0, 2 pi)


@dataclass(frozen=True)
class Pulse:
    """One move as planned: the path the full pulse would follow, and where it touches."""

    move: Move
    path: np.ndarray  # (K + 1, 3): x, y, theta at fractions 0, 1/K, ..., 1 of the pulse
    contact: int | None  # index of the last free sample before the body touched, or None

    def pose_at(self, fraction: float) -> RoverPose:
        """Where the rover is after `fraction` (0..1) of the pulse: held at the contact."""
        k = len(self.path) - 1
        i = min(max(fraction, 0.0), 1.0) * k
        if self.contact is not None and i >= self.contact:
            return _pose(self.path[self.contact])
        lo = int(i)
        if lo >= k:
            return _pose(self.path[k])
        a, b = self.path[lo], self.path[lo + 1]
        w = i - lo
        return _pose(a + (b - a) * w)

    def touched_by(self, fraction: float) -> bool:
        """The body has touched an obstacle within the first `fraction` of the pulse."""
        k = len(self.path) - 1
        return self.contact is not None and min(max(fraction, 0.0), 1.0) * k > self.contact


@dataclass(frozen=True)
class MoveResult:
    pose: RoverPose
    collided: bool


class Rover:
    """One rover on one maze. `plan` a move, then `finish` it after the part of the pulse that ran."""

    def __init__(
        self,
        maze: Maze,
        pose: RoverPose,
        noise: MotionNoise = MotionNoise(),
        seed: int | None = None,
    ) -> None:
        self.maze, self.noise = maze, noise
        self._clearance = clearance_map(maze)
        self._rng = np.random.default_rng(seed)
        where = f"start pose ({pose.x:.3f}, {pose.y:.3f}) m on maze {maze.name!r}"
        if not (0 <= pose.x <= TABLE_WIDTH_M and 0 <= pose.y <= TABLE_HEIGHT_M):
            raise ValueError(f"{where} is off the {TABLE_WIDTH_M} x {TABLE_HEIGHT_M} m table")
        if self.clearance_m(pose.x, pose.y) < BODY_RADIUS_M:
            raise ValueError(
                f"{where} is within {BODY_RADIUS_M:.3f} m (the rover's radius) of a wall, an object or the table's edge"
            )
        self.pose = _pose(np.array([pose.x, pose.y, pose.theta]))

    def clearance_m(self, x: float, y: float) -> float:
        """Distance from (x, y) to the nearest wall, object or table edge, metres."""
        if not (0 <= x <= TABLE_WIDTH_M and 0 <= y <= TABLE_HEIGHT_M):
            return 0.0
        col, row = world_to_pixel(x, y)
        h, w = self._clearance.shape
        return float(self._clearance[min(int(round(float(row))), h - 1), min(int(round(float(col))), w - 1)])

    def plan(self, move: Move | str) -> Pulse:
        """Sample this pulse's error and sweep its path for the first contact."""
        move = Move(move)
        n = self.noise
        x, y, theta = self.pose.x, self.pose.y, self.pose.theta
        if move is Move.FORWARD:
            length = GRID_STEP_M + self._normal(n.forward_m)
            bend = self._normal(n.forward_bend_rad)
            k = max(1, math.ceil(abs(length) / PATH_STEP_M))
            headings = theta + bend * np.arange(k + 1) / k
            # Each sample advances along the mean heading of its interval: a gentle arc.
            mid = theta + bend * (np.arange(k) + 0.5) / k
            step = length / k
            xs = x + np.concatenate([[0.0], np.cumsum(step * np.cos(mid))])
            ys = y + np.concatenate([[0.0], np.cumsum(step * np.sin(mid))])
        else:
            sign = 1.0 if move is Move.LEFT else -1.0
            angle = sign * TURN_RAD + self._normal(n.turn_rad)
            slip_x, slip_y = self._normal(n.turn_slip_m), self._normal(n.turn_slip_m)
            k = max(1, math.ceil(abs(angle) / PATH_STEP_RAD))
            f = np.arange(k + 1) / k
            headings = theta + angle * f
            xs, ys = x + slip_x * f, y + slip_y * f
        path = np.stack([xs, ys, headings], axis=1)
        free = self._free_along(xs, ys)
        blocked = np.flatnonzero(~free)
        contact = None if blocked.size == 0 else max(int(blocked[0]) - 1, 0)
        return Pulse(move, path, contact)

    def finish(self, pulse: Pulse, fraction: float = 1.0) -> MoveResult:
        """The rover is where `fraction` of the pulse took it (a stopped pulse ends early)."""
        self.pose = pulse.pose_at(fraction)
        return MoveResult(self.pose, pulse.touched_by(fraction))

    def move(self, move: Move | str) -> MoveResult:
        """One whole pulse."""
        return self.finish(self.plan(move), 1.0)

    def _normal(self, sd: float) -> float:
        return float(self._rng.normal(0.0, sd)) if sd > 0 else 0.0

    def _free_along(self, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
        on_table = (xs >= 0) & (xs <= TABLE_WIDTH_M) & (ys >= 0) & (ys <= TABLE_HEIGHT_M)
        col, row = world_to_pixel(np.clip(xs, 0, TABLE_WIDTH_M), np.clip(ys, 0, TABLE_HEIGHT_M))
        h, w = self._clearance.shape
        r = np.clip(np.rint(row).astype(np.int64), 0, h - 1)
        c = np.clip(np.rint(col).astype(np.int64), 0, w - 1)
        free = on_table & (self._clearance[r, c] >= BODY_RADIUS_M)
        # The first sample is where the rover already stands: it is never its own obstacle.
        free[0] = True
        return np.asarray(free)


_clearances: weakref.WeakKeyDictionary[Maze, np.ndarray] = weakref.WeakKeyDictionary()


def clearance_map(maze: Maze) -> np.ndarray:
    """Per map pixel, metres to the nearest wall or object pixel or the table's edge."""
    found = _clearances.get(maze)
    if found is None:
        floor = (maze.labels == Label.FLOOR).astype(np.uint8)
        # A frame of obstacle around the table: its edge stops the rover like a wall.
        framed = cv2.copyMakeBorder(floor, 1, 1, 1, 1, cv2.BORDER_CONSTANT, value=0)
        dist = cv2.distanceTransform(framed, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)[1:-1, 1:-1]
        found = _clearances[maze] = dist.astype(np.float64) / PX_PER_M_X
    return found


def _pose(v: Sequence[float] | np.ndarray) -> RoverPose:
    return RoverPose(float(v[0]), float(v[1]), float(v[2]) % (2 * math.pi))

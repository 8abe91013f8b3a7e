"""Where is the rover? A particle filter over continuous (x, y, heading) on a maze.

As in the paper's supplementary material: the moves are odometry (forward 0.07 m, turns of 45
degrees, each with noise), the perceived rays are the measurements. Each particle casts the 13
rays on the maze's label grid and is weighted by how well their labels and depths agree with
what the camera read; low-variance resampling keeps the cloud on the likely poses, and a few
particles drawn anew over the free space at each resampling let it recover from a wrong
early lock. The belief starts uniform over the free space (the rover could be anywhere).
"""

from __future__ import annotations

import weakref
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TypedDict

import cv2
import numpy as np
from tqdm import tqdm

from sim.core.dynamics import Action
from sim.core.geometry import GRID_STEP_M, TABLE_HEIGHT_M, TABLE_WIDTH_M, TURN_RAD, world_to_pixel
from sim.core.labels import N_LABELS, Label
from sim.core.maze import Maze
from sim.core.observations import PX_PER_M_X, RAY_OFFSETS, WALL_CLEARANCE_M, ray_caster
from sim.core.rays import RayObservation
from sim.robot.camera import CameraCalibration, FrontCamera, capture
from sim.robot.perception import evaluation_rig, perceive

DEPTH_CAP_M = 2.0  # beyond this a depth says little (the wall base is near the horizon)


@dataclass(frozen=True)
class MotionNoise:
    """Odometry error per move: forward distance, heading change during a forward move, turn."""

    forward_std_m: float = 0.006
    drift_std_rad: float = np.deg2rad(1.5)
    turn_std_rad: float = np.deg2rad(3.0)


@dataclass(frozen=True)
class SensorModel:
    """How much a perceived ray is trusted."""

    label_hit: float = 0.85  # probability that a read label is the true one
    depth_std_m: float = 0.03  # at zero distance, growing with distance
    depth_std_per_m: float = 0.08
    outlier: float = 0.15  # weight of a depth that matches nothing (an object drawn elsewhere)
    temperature: float = 2.0  # rays of one frame are not independent: soften their product


class FreeSpace:
    """Where the rover's centre may be: at least the simulator's wall clearance from every wall
    pixel of the walls-only map (objects are driven over, as in the navigation graph)."""

    def __init__(self, maze: Maze, clearance_m: float = WALL_CLEARANCE_M):
        dist_px = cv2.distanceTransform((maze.walls == Label.FLOOR).astype(np.uint8), cv2.DIST_L2, 5)
        free = dist_px >= clearance_m * PX_PER_M_X
        self.shape: tuple[int, int] = free.shape
        # The free cells as runs along the flattened rows (where each starts and ends, and how
        # many free cells come before it), not a grid: some 100 kB a maze instead of 1.6 MB (a
        # bool grid) or 3.5 MB (a list of every cell), and a server holds one per live trial's
        # maze. A cell is found by a binary search, so a sample draws the same cells, and
        # `contains` says the same, as the grid would.
        flat = np.concatenate([[False], free.ravel(), [False]])
        edges = np.flatnonzero(flat[1:] != flat[:-1])
        starts, ends = edges[0::2], edges[1::2]
        lengths = ends - starts
        self._run_starts = starts.astype(np.int32)
        self._run_ends = ends.astype(np.int32)
        self._run_first = (np.cumsum(lengths) - lengths).astype(np.int64)
        self.n_cells = int(lengths.sum())
        if self.n_cells == 0:
            raise ValueError(f"maze {maze.name!r} has no free space for the rover")

    def contains(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        col, row = world_to_pixel(x, y)
        c, r = np.rint(col).astype(np.int64), np.rint(row).astype(np.int64)
        h, w = self.shape
        ok = (c >= 0) & (c < w) & (r >= 0) & (r < h)
        k = r[ok] * w + c[ok]
        run = np.searchsorted(self._run_starts, k, side="right") - 1
        out = np.zeros(np.shape(x), dtype=bool)
        out[ok] = (run >= 0) & (k < self._run_ends[np.maximum(run, 0)])
        return out

    def sample(self, n: int, rng: np.random.Generator) -> np.ndarray:
        """(n, 3) poses uniform over the free space, headings uniform."""
        k = rng.integers(0, self.n_cells, n)
        run = np.searchsorted(self._run_first, k, side="right") - 1
        h, w = self.shape
        rows, cols = np.divmod(self._run_starts[run] + (k - self._run_first[run]), w)
        x = (cols + rng.uniform(-0.5, 0.5, n)) / (w - 1) * TABLE_WIDTH_M
        y = (1 - (rows + rng.uniform(-0.5, 0.5, n)) / (h - 1)) * TABLE_HEIGHT_M
        return np.column_stack(
            [np.clip(x, 0, TABLE_WIDTH_M), np.clip(y, 0, TABLE_HEIGHT_M), rng.uniform(-np.pi, np.pi, n)]
        )


_free_spaces: weakref.WeakKeyDictionary[Maze, FreeSpace] = weakref.WeakKeyDictionary()


def free_space(maze: Maze) -> FreeSpace:
    space = _free_spaces.get(maze)
    if space is None:
        space = _free_spaces[maze] = FreeSpace(maze)
    return space


def apply_move(
    poses: np.ndarray, action: Action, rng: np.random.Generator, space: FreeSpace, noise: MotionNoise = MotionNoise()
) -> tuple[np.ndarray, np.ndarray]:
    """Poses (N, 3) after one move, each with its own noise; a forward move that would leave the
    free space stops where it was (the rover stops at the wall). Returns (poses, collided)."""
    poses = np.array(poses, dtype=np.float64, copy=True)
    n = len(poses)
    collided = np.zeros(n, dtype=bool)
    if action == Action.FORWARD:
        dist = GRID_STEP_M + rng.normal(0, noise.forward_std_m, n) if noise.forward_std_m else GRID_STEP_M
        theta = poses[:, 2] + (rng.normal(0, noise.drift_std_rad, n) if noise.drift_std_rad else 0)
        x = poses[:, 0] + dist * np.cos(theta)
        y = poses[:, 1] + dist * np.sin(theta)
        ok = space.contains(x, y)
        poses[ok, 0], poses[ok, 1], poses[:, 2] = x[ok], y[ok], theta
        collided = ~ok
    elif action in (Action.LEFT, Action.RIGHT):
        sign = 1.0 if action == Action.LEFT else -1.0
        turn = sign * TURN_RAD + (rng.normal(0, noise.turn_std_rad, n) if noise.turn_std_rad else 0)
        poses[:, 2] += turn
    poses[:, 2] = (poses[:, 2] + np.pi) % (2 * np.pi) - np.pi
    return poses, collided


class FilterResult(TypedDict):
    converged_fraction_20_moves: float
    err_median_m_20_moves: float
    curve: list[float]  # median error of the belief's mean after each move, from the start
    episodes: int
    moves: int
    particles: int


@dataclass(frozen=True)
class Belief:
    x: float
    y: float
    heading: float  # radians, circular mean
    spread_m: float  # root mean square distance of the particles from (x, y)
    cloud: np.ndarray  # (K <= 200, 4): x, y, heading, weight (weights sum to 1)


class ParticleFilter:
    """Belief over the rover's pose on `maze`, from moves and perceived rays."""

    def __init__(
        self,
        maze: Maze,
        n_particles: int = 1500,
        seed: int | None = None,
        motion: MotionNoise = MotionNoise(),
        sensor: SensorModel = SensorModel(),
        inject: float = 0.02,
        initial_factor: int = 5,
        converged_particles: int | None = None,
        converged_m: float = 0.05,
    ):
        """`converged_particles`: resample to this many (fewer) while the cloud's spread is under
        `converged_m` (a tight cloud needs few particles; the casts cost in proportion), back to
        `n_particles` once it spreads."""
        if n_particles < 10 or (converged_particles is not None and not 10 <= converged_particles <= n_particles):
            raise ValueError(f"particle counts must be at least 10, got {n_particles} and {converged_particles}")
        self.maze, self.motion, self.sensor, self.inject = maze, motion, sensor, inject
        self.converged_particles, self.converged_m = converged_particles, converged_m
        self.rng = np.random.default_rng(seed)
        self.space = free_space(maze)
        self.caster = ray_caster(maze)
        self.n, self.initial_factor = n_particles, max(int(initial_factor), 1)
        self.reset()

    def reset(self) -> None:
        """Uniform over the free space, `initial_factor` times denser than the filter runs: from
        a uniform start few particles lie near the truth, and the first frame picks them out."""
        self.particles = self.space.sample(self.n * self.initial_factor, self.rng)
        self.log_w = np.zeros(len(self.particles))

    @property
    def weights(self) -> np.ndarray:
        w: np.ndarray = np.exp(self.log_w - self.log_w.max())
        weights: np.ndarray = w / w.sum()
        return weights

    def move(self, action: Action) -> None:
        self.particles, _ = apply_move(self.particles, Action(action), self.rng, self.space, self.motion)

    def update(self, obs: RayObservation) -> None:
        """Weigh the particles by the observation, then resample if the weights have collapsed."""
        if obs.problem is not None or not obs.valid.any():
            return  # an unreadable frame says nothing about the pose
        rays = np.nonzero(obs.valid)[0]
        p = self.particles
        labels, depth = self.caster.cast(p[:, 0, None], p[:, 1, None], p[:, 2, None] + RAY_OFFSETS[rays])
        s = self.sensor
        miss = (1 - s.label_hit) / (N_LABELS - 1)
        log_label = np.where(labels == obs.labels[rays], np.log(s.label_hit), np.log(miss))
        seen = np.minimum(obs.depth[rays], DEPTH_CAP_M)
        expected = np.minimum(depth, DEPTH_CAP_M)
        std = s.depth_std_m + s.depth_std_per_m * seen
        gauss = np.exp(-0.5 * ((expected - seen) / std) ** 2) / (std * np.sqrt(2 * np.pi))
        log_depth = np.log((1 - s.outlier) * gauss + s.outlier / DEPTH_CAP_M)
        self.log_w += (log_label + log_depth).sum(axis=1) / s.temperature
        self.log_w -= self.log_w.max()
        w = self.weights
        n = self._target_count(w)
        if 1.0 / np.sum(w * w) < len(w) / 2 or len(w) > n:
            self._resample(w, n)

    def _target_count(self, w: np.ndarray) -> int:
        if self.converged_particles is None:
            return self.n
        p = self.particles
        x, y = w @ p[:, 0], w @ p[:, 1]
        spread = np.sqrt(w @ ((p[:, 0] - x) ** 2 + (p[:, 1] - y) ** 2))
        return self.converged_particles if spread < self.converged_m else self.n

    def _resample(self, w: np.ndarray, n: int) -> None:
        """Low-variance (systematic) resampling to `n` particles, a little jitter, and some
        fresh ones."""
        positions = (self.rng.random() + np.arange(n)) / n
        idx = np.minimum(np.searchsorted(np.cumsum(w), positions), len(w) - 1)
        p = self.particles[idx]
        jitter = self.rng.normal(0, [0.005, 0.005, np.deg2rad(1.0)], p.shape)
        moved = p + jitter
        ok = self.space.contains(moved[:, 0], moved[:, 1])
        p[ok] = moved[ok]
        fresh = self.rng.random(n) < self.inject
        p[fresh] = self.space.sample(int(fresh.sum()), self.rng)
        self.particles = p
        self.log_w = np.zeros(n)

    def belief(self, max_points: int = 200) -> Belief:
        w = self.weights
        p = self.particles
        x, y = float(w @ p[:, 0]), float(w @ p[:, 1])
        heading = float(np.arctan2(w @ np.sin(p[:, 2]), w @ np.cos(p[:, 2])))
        spread = float(np.sqrt(w @ ((p[:, 0] - x) ** 2 + (p[:, 1] - y) ** 2)))
        # The cloud: a systematic draw of max_points, duplicates merged with their weight.
        positions = (0.5 + np.arange(max_points)) / max_points
        idx = np.minimum(np.searchsorted(np.cumsum(w), positions), len(w) - 1)
        unique, counts = np.unique(idx, return_counts=True)
        cloud = np.column_stack([p[unique], counts / max_points])
        return Belief(x, y, heading, spread, cloud)


# -- measured on simulated episodes -------------------------------------------------------------


def _explore_action(pose: np.ndarray, space: FreeSpace, rng: np.random.Generator) -> Action:
    """A wandering Driver: forward while the way is clear, sometimes a turn."""
    ahead = pose[:2] + 2 * GRID_STEP_M * np.array([np.cos(pose[2]), np.sin(pose[2])])
    if space.contains(ahead[0:1], ahead[1:2])[0] and rng.random() < 0.75:
        return Action.FORWARD
    return Action.LEFT if rng.random() < 0.5 else Action.RIGHT


def evaluate_filter(
    mazes: Maze | Sequence[Maze],
    episodes: int = 20,
    moves: int = 20,
    seed: int = 0,
    n_particles: int = 1500,
    converged_particles: int | None = None,
    camera: FrontCamera | None = None,
    calibration: CameraCalibration | None = None,
    progress: bool = False,
) -> FilterResult:
    """Episodes from a uniform belief: the true rover moves with the filter's own noise model
    (collisions stop it), each frame goes through the camera model and perception, the filter gets
    the moves and the perceived rays. Error = distance from the belief's mean to the true position."""
    worlds, camera, calibration = evaluation_rig(mazes, seed, camera, calibration)
    rng = np.random.default_rng(seed)
    errors = np.zeros((episodes, moves + 1))
    for e in tqdm(range(episodes), "particle filter", disable=not progress):
        maze = worlds[e % len(worlds)][0]
        space = free_space(maze)
        pf = ParticleFilter(maze, n_particles, seed=int(rng.integers(2**31)), converged_particles=converged_particles)
        truth = space.sample(1, rng)
        for t in range(moves + 1):
            if t > 0:
                action = _explore_action(truth[0], space, rng)
                truth, _ = apply_move(truth, action, rng, space)
                pf.move(action)
            x, y, theta = truth[0]
            pf.update(perceive(capture(maze, x, y, theta, camera, rng), calibration))
            b = pf.belief()
            errors[e, t] = np.hypot(b.x - x, b.y - y)
    final = errors[:, -1]
    return {
        "converged_fraction_20_moves": float((final <= 0.15).mean()),  # within 0.15 m
        "err_median_m_20_moves": float(np.median(final)),
        "curve": [float(v) for v in np.median(errors, axis=0)],
        "episodes": episodes,
        "moves": moves,
        "particles": n_particles,
    }

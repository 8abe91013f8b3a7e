"""The replay simulation's observations: 13 rays over a 78 degree field of view.

Each ray starts at the agent's exact position and returns the label of the first non-floor
pixel it meets on the maze's `labels` grid (walls and objects, `maze.map-fixed.png`), its
distance in metres, and whether that wall is too close to move toward. With the
forward-blocked flag of the navigation graph, that is the observation of the paper's agent.
Everything is static per (node, heading), so `RayTable` precomputes it for a whole graph.

Rays visit every pixel whose square they cross (a supercover traversal, so a ray that clips
the corner of a wall sees it), jumping across open floor as far as the map's distance
transform guarantees no wall pixel is skipped. Depths are exact to the pixel grid.
"""

from __future__ import annotations

import hashlib
import weakref
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import ArrayLike

from sim.core.cache import ARRAYS_SUFFIX, load_arrays, save_arrays
from sim.core.cache import cache_dir as default_cache_dir
from sim.core.geometry import (
    GRID_STEP_M,
    HEADINGS,
    MAP_HEIGHT_PX,
    MAP_WIDTH_PX,
    TABLE_HEIGHT_M,
    TABLE_WIDTH_M,
    TURN_RAD,
)
from sim.core.labels import N_LABELS, Label
from sim.core.maze import Maze
from sim.core.navgraph import WALL_CLEARANCE_PX, NavGraph
from sim.core.rays import RayObservation

N_RAYS = 13
FOV_DEG = 78.0
RAY_OFFSETS = np.deg2rad(np.linspace(-FOV_DEG / 2, FOV_DEG / 2, N_RAYS))  # left of heading is +

# Pixels per metre along each axis (the raster is very slightly anisotropic).
PX_PER_M_X = (MAP_WIDTH_PX - 1) / TABLE_WIDTH_M
PX_PER_M_Y = (MAP_HEIGHT_PX - 1) / TABLE_HEIGHT_M

# The navigation graph removes grid points with a wall pixel in the square around them, so a
# forward move collides when it would end that close to a wall. A ray is "too close" when one
# forward move along it would end within that clearance: depth < step + clearance, the
# simulator's own collision rule, so a wall flagged straight ahead always blocks the move. The
# square reaches 40 px up and left of the node's truncated pixel but 39 down and right, and
# truncation loses up to one more: 38 px is the clearance it keeps on every side. (The robot's
# half length, 0.127 m, is larger, and would flag walls the simulator lets the agent drive up to.)
WALL_CLEARANCE_M = (WALL_CLEARANCE_PX - 2) / PX_PER_M_X
STEP_M = np.where(np.arange(HEADINGS) % 2 == 0, 1.0, np.sqrt(2)) * GRID_STEP_M  # per heading
TOO_CLOSE_M = STEP_M + WALL_CLEARANCE_M  # (8,) threshold per heading

# Flat feature vector per (node, heading): one-hot label per ray, depth per ray (metres),
# too-close per ray, forward blocked.
OBS_FEATURES = N_RAYS * N_LABELS + N_RAYS + N_RAYS + 1

CHAMFER_SAFETY = 0.96
CLEARANCE_BLOCK = 4  # the clearance is kept per 4x4-pixel block (as shift: BLOCK_SHIFT)
BLOCK_SHIFT = CLEARANCE_BLOCK.bit_length() - 1
_SAFE_PX = 1.5  # a point is at most sqrt(2)/2 px from its pixel's centre, on both ends of a jump
_PAST_PX = np.float32(1e-3)  # a crossing's sample lies this far into the pixel entered
_FAR = 1e9  # boundary gap of an axis a ray never crosses
CACHE_VERSION = 2  # 2: exact traversal (1 could skip a grazed wall corner)


class RayCaster:
    """Casts rays on one label grid, from any continuous pose."""

    def __init__(self, labels: np.ndarray):
        self.labels = np.ascontiguousarray(labels, dtype=np.uint8)
        # Distance (px) from each pixel centre to the nearest non-floor pixel centre, never
        # more: the 5x5 chamfer transform overestimates by at most 2%, so it is scaled down. A
        # ray only needs a lower bound to jump by, so it is kept small: the least over each
        # 4x4 block, in whole pixels, at most 255 (0.1 MB a maze instead of 6.6 MB of float32;
        # a server holds one per live trial's maze). The rays meet the same pixels; they take a
        # few more jumps to get there.
        floor = (self.labels == Label.FLOOR).view(np.uint8)  # the bools' bytes: no copy to convert
        chamfer = cv2.distanceTransform(floor, cv2.DIST_L2, cv2.DIST_MASK_5)
        self.clearance = _block_min_px(chamfer, CLEARANCE_BLOCK, np.float32(CHAMFER_SAFETY))

    def cast(self, x: ArrayLike, y: ArrayLike, angles: ArrayLike, window: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """Rays from (x, y) metres at absolute angles (radians, broadcast together).

        Returns (labels uint8, depth float64 metres) shaped like the broadcast: the first pixel
        whose square the ray enters that is not floor, and the distance to where it enters. A
        ray that leaves the table without meeting anything returns FLOOR and the distance to
        the edge. Each round checks the pixels entered at the next `window` pixel-boundary
        crossings (more per round helps rays that run along a wall), then jumps as far as the
        distance transform allows.
        """
        x, y, angles = (np.asarray(a, np.float64) for a in (x, y, angles))
        shape = np.broadcast_shapes(x.shape, y.shape, angles.shape)
        xs, ys = (a.ravel() for a in np.broadcast_arrays(x, y))
        outside = (xs < 0) | (xs > TABLE_WIDTH_M) | (ys < 0) | (ys > TABLE_HEIGHT_M)
        if outside.any():
            i = int(np.argmax(outside))
            raise ValueError(
                f"ray origin ({xs[i]:.3f}, {ys[i]:.3f}) m is off the {TABLE_WIDTH_M} x {TABLE_HEIGHT_M} m table"
            )
        h, w = self.labels.shape
        f32 = np.float32
        # What depends on the direction alone is computed on the angles' own shape (a node table
        # has 104 of them), and broadcast into the state below.
        dc = np.cos(angles) * PX_PER_M_X
        dr = -np.sin(angles) * PX_PER_M_Y
        px_per_m = np.hypot(dc, dr)  # pixels travelled per metre along each ray
        uc, ur = (dc / px_per_m).astype(f32), (dr / px_per_m).astype(f32)
        # Distance along the ray between successive column (row) boundaries, and which side
        # of its pixel the next boundary is on (1 ahead in +col, 0 behind).
        with np.errstate(divide="ignore"):
            gap_c = np.where(uc != 0, 1 / np.abs(uc), _FAR).astype(f32)
            gap_r = np.where(ur != 0, 1 / np.abs(ur), _FAR).astype(f32)
        side_c, side_r = (uc > 0).astype(f32), (ur > 0).astype(f32)
        # The state of every ray, one row per quantity (column, row pairs side by side, so that
        # one numpy call does both axes): origin, direction, boundary gaps, sides, exit. Positions
        # shifted by half a pixel: pixel (col, row) is the unit square at [col, col + 1) x
        # [row, row + 1), so truncation finds the pixel a point is in. Marched in float32: a
        # ten-thousandth of a pixel at the far edge.
        state = np.empty((9, *shape), dtype=f32)
        state[0] = (x * PX_PER_M_X + 0.5).astype(f32)
        state[1] = ((h - 0.5) - y * PX_PER_M_Y).astype(f32)
        for row, part in enumerate((uc, ur, gap_c, gap_r, side_c, side_r), start=2):
            state[row] = part
        state[8] = np.minimum(_exit_time(state[0], state[2], w), _exit_time(state[1], state[3], h))
        n = state[0].size
        state = state.reshape(9, n)
        flat_labels, flat_clear = self.labels.ravel(), self.clearance.ravel()
        block_w = self.clearance.shape[1]
        k = np.arange(window, dtype=f32)

        hit_label = np.zeros(n, dtype=np.uint8)
        hit_t = np.zeros(n, dtype=f32)
        # The rays still marching: their ids, state and t. Compacted once a quarter of them have
        # stopped (every round cost more in copies than the stopped ones cost marching on: they
        # stay on the table, clamped at its edge, and are not recorded again).
        ids = np.arange(n)
        t = np.zeros(n, dtype=f32)
        marching = np.ones(n, dtype=bool)
        left = n
        while left:
            origin, direction, gap, side, te = state[0:2], state[2:4], state[4:6], state[6:8], state[8]
            # Samples: the point at t, then just past each of the next boundary crossings.
            to = direction * t
            to += origin
            corner = np.floor(to)
            to -= corner
            np.subtract(side, to, out=to)
            np.abs(to, out=to)
            to *= gap  # (2, n): distance to the next column boundary, and to the next row boundary
            if window == 1:
                ts, ends = t, te
                advance = np.minimum(to[0], to[1])
                px = corner.astype(np.intp)
            else:
                cross = np.sort(
                    np.concatenate(
                        [to[0][:, None] + k * gap[0][:, None], to[1][:, None] + k * gap[1][:, None]], axis=1
                    ),
                    axis=1,
                )[:, :window]
                advance = cross[:, -1]
                cross[:, 1:] = cross[:, :-1] + _PAST_PX
                cross[:, 0] = 0
                ends = te[:, None]
                ts = np.minimum(t[:, None] + cross, ends)
                px = (origin[:, :, None] + direction[:, :, None] * ts).astype(np.intp)
            # intp indices: numpy converts any other to intp first, which cost more than the gather.
            label = flat_labels.take(px[1] * w + px[0])
            stop = label != 0
            stop |= ts >= ends
            px >>= BLOCK_SHIFT
            reach = ts + flat_clear.take(px[1] * block_w + px[0])
            if window == 1:
                done, at = stop, ts
            else:
                rows, first = np.arange(ids.size), stop.argmax(axis=1)
                done, label, at, reach = stop[rows, first], label[rows, first], ts[rows, first], reach.max(axis=1)
            t = t + advance
            t += _PAST_PX
            reach -= _SAFE_PX
            np.maximum(t, reach, out=t)
            np.minimum(t, te, out=t)  # exits at the edge
            # A few of the many: indices, not masks (`nonzero` itself: `np.flatnonzero` is three Python calls
            # around it, and most rounds march a few hundred rays, where the calls are the cost).
            stopped = (done & marching).nonzero()[0]
            if stopped.size:
                rays = ids[stopped]
                hit_label[rays], hit_t[rays] = label[stopped], at[stopped]
                marching[stopped] = False
                left -= stopped.size
                if left <= ids.size * 3 // 4:
                    keep = marching.nonzero()[0]
                    state, ids, t = state.take(keep, axis=1), ids.take(keep), t.take(keep)
                    marching = np.ones(left, dtype=bool)
        # Where the ray entered the pixel it stopped in.
        hit_t = np.where(hit_t > 0, hit_t - _PAST_PX, 0).astype(np.float64)
        return hit_label.reshape(shape), (hit_t / np.broadcast_to(px_per_m, shape).ravel()).reshape(shape)


def _block_min_px(distance: np.ndarray, block: int, scale: np.float32) -> np.ndarray:
    """uint8 (ceil(H / block), ceil(W / block)): the least of `distance * scale` over each block,
    in whole pixels rounded down and capped at 255 (a lower bound for every pixel of the block); 0
    for a block the map's edge cuts. Scaled after the least is taken: rounding a product is
    monotonic, so the least of the products is the product of the least."""
    h, w = distance.shape
    full_h, full_w = h // block, w // block
    least = np.zeros((-(-h // block), -(-w // block)), dtype=np.float32)
    # The least of strided slices, pairwise into one buffer: a reduction over an axis of 4 cost
    # three times as much, and `np.minimum.reduce` over a list of slices first copies them all.
    whole = distance[: full_h * block, : full_w * block]
    rows = _least_of([whole[k::block] for k in range(block)])
    least[:full_h, :full_w] = _least_of([rows[:, k::block] for k in range(block)]) * scale
    clearance: np.ndarray = np.minimum(np.floor(least), 255).astype(np.uint8)
    return clearance


def _least_of(parts: list[np.ndarray]) -> np.ndarray:
    """The elementwise least of same-shaped arrays, in a buffer of its own."""
    least: np.ndarray = np.minimum(parts[0], parts[1])
    for part in parts[2:]:
        np.minimum(least, part, out=least)
    return least


def _exit_time(p0: np.ndarray, u: np.ndarray, size: int) -> np.ndarray:
    """Distance along unit direction u from p0 (shifted half a pixel) to the raster's edge."""
    inside = 1e-3  # stop just short of the edge, so truncation stays a valid index
    with np.errstate(divide="ignore"):
        t_hi = np.where(u > 0, (size - inside - p0) / u, np.inf)
        t_lo = np.where(u < 0, (inside - p0) / u, np.inf)
    return np.minimum(t_hi, t_lo)


_casters: weakref.WeakKeyDictionary[Maze, RayCaster] = weakref.WeakKeyDictionary()


def ray_caster(maze: Maze) -> RayCaster:
    """The maze's caster on its `labels` grid (objects visible), built once per maze."""
    caster = _casters.get(maze)
    if caster is None:
        caster = _casters[maze] = RayCaster(maze.labels)
    return caster


def cast_rays(
    maze: Maze, x: float, y: float, theta: float, offsets: ArrayLike = RAY_OFFSETS
) -> tuple[np.ndarray, np.ndarray]:
    """The observation rays from a continuous pose: (labels (13,), depth (13,) metres)."""
    return ray_caster(maze).cast(x, y, theta + np.asarray(offsets))


def too_close(depth: ArrayLike, heading: ArrayLike) -> np.ndarray:
    """Whether a forward move at `heading` (index 0..7) toward a wall `depth` metres away would
    end within the navigation graph's wall clearance."""
    close: np.ndarray = np.asarray(depth) < TOO_CLOSE_M[np.asarray(heading) % HEADINGS]
    return close


@dataclass(frozen=True, eq=False)
class RayTable:
    labels: np.ndarray  # (N, 8, 13) uint8 Label of the first non-floor pixel per ray
    depth: np.ndarray  # (N, 8, 13) float32 metres
    too_close: np.ndarray  # (N, 8, 13) bool
    forward_blocked: np.ndarray  # (N, 8) bool

    @classmethod
    def build(
        cls, maze: Maze, graph: NavGraph, cache_dir: str | Path | None = None, use_cache: bool = True
    ) -> RayTable:
        """Every (node, heading) observation of `graph` on `maze`, cached by maze and nodes."""
        labels: np.ndarray | None = None
        depth: np.ndarray | None = None
        path = None  # no key to hash without the cache
        if use_cache:
            key = hashlib.sha256(np.ascontiguousarray(graph.nodes).tobytes()).hexdigest()[:12]
            path = default_cache_dir(cache_dir) / "rays" / f"{maze.content_hash}-{key}-v{CACHE_VERSION}{ARRAYS_SUFFIX}"
        if path is not None and path.exists():
            try:
                data = load_arrays(path)
                labels, depth = data["labels"], data["depth"]
            except (OSError, ValueError, KeyError):
                labels = None  # a torn or stale cache file is rebuilt below
        if labels is None or labels.shape != (graph.n, HEADINGS, N_RAYS):
            labels, depth = node_rays(maze, graph.nodes)
            if path is not None:
                save_arrays(path, labels=labels, depth=depth)
        assert depth is not None  # read or built with the labels
        return cls(
            labels=labels,
            depth=depth,
            too_close=too_close(depth, np.arange(HEADINGS)[None, :, None]),
            forward_blocked=graph.forward < 0,
        )

    def observation(self, node: int, heading: int) -> RayObservation:
        """What the camera sees at a pose: every ray read."""
        return RayObservation(
            labels=self.labels[node, heading],
            depth=self.depth[node, heading],
            too_close=self.too_close[node, heading],
            valid=np.ones(self.labels.shape[-1], dtype=bool),
            forward_blocked=bool(self.forward_blocked[node, heading]),
        )

    def features(self) -> np.ndarray:
        """(N, 8, OBS_FEATURES) float32: one-hot labels (13 x 10), depths, too-close, blocked."""
        n = self.labels.shape[0]
        out = np.zeros((n, HEADINGS, OBS_FEATURES), dtype=np.float32)
        onehot = out[..., : N_RAYS * N_LABELS].reshape(n, HEADINGS, N_RAYS, N_LABELS)
        np.put_along_axis(onehot, self.labels[..., None].astype(np.int64), 1.0, axis=-1)
        start = N_RAYS * N_LABELS
        out[..., start : start + N_RAYS] = self.depth
        out[..., start + N_RAYS : start + 2 * N_RAYS] = self.too_close
        out[..., -1] = self.forward_blocked
        return out


def node_rays(maze: Maze, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rays for every node position and heading: labels (N, 8, 13) uint8, depth float32."""
    angles = np.arange(HEADINGS)[:, None] * TURN_RAD + RAY_OFFSETS[None, :]  # (8, 13)
    nodes = np.asarray(nodes, dtype=np.float64)
    # A caster of its own: tables are built for many mazes at once, and the caster's maps
    # need not outlive the table.
    labels, depth = RayCaster(maze.labels).cast(nodes[:, 0, None, None], nodes[:, 1, None, None], angles[None])
    return labels, depth.astype(np.float32)

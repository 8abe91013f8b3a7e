"""Pictures of the simulated maze: the Driver's first-person camera and a top-down view.

The camera is a column ray caster: one ray per image column on the walls-only grid, each wall
column drawn with a height falling off with distance, shaded by how squarely the ray meets the
wall and by distance. The grid is turned once per maze into its floor-to-wall pixel edges,
merged into straight runs (about 3,800 a map); a frame meets only the edges facing the camera,
each against the few columns its ends project to, so a ray's hit is exactly the pixel the
grid march of `sim.core.observations.RayCaster` stops at. The objects (jar, mug, paddle) stand on
their footprints on the map (`maze.labels`): a second cast against the objects' own edges
draws each as a solid of its colour and height rising from exactly where the observation rays
meet it, in front of the walls it is nearer than, so a ray's label and depth can be read off
the picture as `RayTable` gives them.

What a frame needs of a maze (`Scene`) is built once and cached on disk by the maze's contents
(`cached_scene`, `load_scene`): the edges, the grids as runs (a pixel is a binary search), and the
walls' normals only on the band along the walls that a ray can enter, about 1 MB a maze where the
maze and a full normal field are 17 MB, so a render process keeps every live maze's scene.
"""

from __future__ import annotations

import threading
import weakref
from collections.abc import Sequence
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Literal

import cv2
import numpy as np
from numpy.typing import ArrayLike

from sim.core.cache import ARRAYS_SUFFIX, load_arrays, save_arrays
from sim.core.cache import cache_dir as default_cache_dir
from sim.core.geometry import world_to_pixel
from sim.core.labels import LABEL_BGR, N_LABELS, OBJECT_LABELS, PALETTE_BGR, Label
from sim.core.maze import Maze, pixels_of
from sim.core.observations import FOV_DEG, PX_PER_M_X, PX_PER_M_Y, RAY_OFFSETS, cast_rays

# The camera: the paper's 78 degree field of view, low on the rover, looking level.
CAMERA_HEIGHT_M = 0.05
WALL_HEIGHT_M = 0.12
HORIZON = 0.42  # image row of the horizon, as a fraction of the height
FOG_M = 3.0  # distance at which colours have faded to half

# The room beyond the table, and the table top (BGR).
SKY_TOP, SKY_HORIZON = np.array([120, 104, 92.0]), np.array([200, 196, 190.0])
FLOOR_NEAR, FLOOR_FAR = np.array([58, 58, 62.0]), np.array([22, 22, 24.0])
OUTLINE = 0.45  # brightness of wall edges
_NO_HIT = np.array(np.inf).view(np.int64)  # a column key: no wall met (label FLOOR)
NORMAL_BAND_PX = 3  # normals are kept for pixels this near both a wall and the floor
_FOOTPRINT = np.full(256, Label.FLOOR, dtype=np.uint8)  # a label to itself if an object's, else floor
_FOOTPRINT[list(OBJECT_LABELS)] = list(OBJECT_LABELS)
SCENE_CACHE_VERSION = 1


@dataclass(frozen=True, eq=False)
class _Grid:
    """A label grid as its runs along the flattened rows: a pixel is a binary search."""

    shape: tuple[int, int]
    starts: np.ndarray  # (R,) int32 flat index where each run begins
    values: np.ndarray  # (R,) uint8 its label

    @classmethod
    def of(cls, grid: np.ndarray) -> _Grid:
        flat = np.ascontiguousarray(grid, dtype=np.uint8).ravel()
        starts = np.flatnonzero(np.concatenate([[True], flat[1:] != flat[:-1]])).astype(np.int32)
        return cls((int(grid.shape[0]), int(grid.shape[1])), starts, flat[starts])

    def __getitem__(self, at: tuple[int, int]) -> int:
        row, col = at
        return int(self.values[np.searchsorted(self.starts, row * self.shape[1] + col, side="right") - 1])

    def array(self) -> np.ndarray:
        lengths = np.diff(np.append(self.starts, self.shape[0] * self.shape[1]))
        return np.repeat(self.values, lengths).reshape(self.shape)


@dataclass(frozen=True, eq=False)
class _Edges:
    """Floor-to-wall pixel edges of one orientation, merged into straight runs of one label and
    sorted by where they stand: `at` the fixed coordinate (x of a vertical edge, y of a
    horizontal one), `lo`..`hi` the extent along the other axis, metres."""

    vertical: bool
    floor_below: bool  # the floor is on the side of smaller `at`: seen only from there
    at: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    label: np.ndarray  # int64 label of the wall pixel entered across the edge

    def facing(self, x: float, y: float) -> slice:
        """The edges whose floor side the camera is on: a ray reaches a wall only through those."""
        i = int(np.searchsorted(self.at, x if self.vertical else y))
        return slice(i, None) if self.floor_below else slice(0, i)


@dataclass(frozen=True, eq=False)
class _Walls:
    """The walls grid as its edges: a ray from the floor first enters a wall pixel where it
    crosses the nearest edge it meets from the floor side."""

    edges: tuple[_Edges, ...]
    grid: _Grid  # the walls grid: is the camera inside a wall?


def _edge_runs(entered: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Runs of equal non-zero labels along each row of `entered` (N, L): row, first, end, label."""
    n, length = entered.shape
    padded = np.zeros((n, length + 2), dtype=entered.dtype)
    padded[:, 1:-1] = entered
    change = np.flatnonzero(padded[:, 1:] != padded[:, :-1])
    lane, at = np.divmod(change, length + 1)
    value, previous = padded[lane, at + 1], padded[lane, at]
    starts = np.flatnonzero(value != 0)  # every change into a label opens a run ...
    ends = np.flatnonzero(previous != 0)  # ... and every change out of one closes it, in order
    return lane[starts], at[starts], at[ends], value[starts].astype(np.int64)


def _walls(grid: np.ndarray) -> _Walls:
    h, w = grid.shape
    # Edges only where the floor meets the rest: the box around what is not floor, and a pixel
    # of floor round it (the objects' footprints are a few per cent of the map).
    solid = grid != Label.FLOOR
    rows, cols = np.flatnonzero(solid.any(axis=1)), np.flatnonzero(solid.any(axis=0))
    r0, c0 = (max(int(rows[0]) - 1, 0), max(int(cols[0]) - 1, 0)) if rows.size else (0, 0)
    r1, c1 = (int(rows[-1]) + 2, int(cols[-1]) + 2) if rows.size else (h, w)
    box = grid[r0:r1, c0:c1]
    floor = ~solid[r0:r1, c0:c1]
    # Pixel boundaries in metres: column boundary c (between pixels c - 1 and c), row boundary r.
    col_x = (np.arange(c0, min(c1, w) + 1) - 0.5) / PX_PER_M_X
    row_y = ((h - 0.5) - np.arange(r0, min(r1, h) + 1)) / PX_PER_M_Y
    edges = []
    for vertical in (True, False):
        lanes = box.T if vertical else box  # a lane runs along the edges' extent
        free = floor.T if vertical else floor
        for into_next in (True, False):  # the wall pixel is the next one across the lane, or the previous
            wall_px = lanes[1:] if into_next else lanes[:-1]
            entered = np.where(free[:-1] if into_next else free[1:], wall_px, 0)
            lane, first, end, label = _edge_runs(entered)
            if vertical:  # lane: column boundary lane + 1; extent: rows first..end, y decreasing
                at, lo, hi = col_x[lane + 1], row_y[end], row_y[first]
                floor_below = into_next  # the wall at larger x
            else:  # lane: row boundary lane + 1; extent: columns first..end
                at, lo, hi = row_y[lane + 1], col_x[first], col_x[end]
                floor_below = not into_next  # rows grow downward: the next row is at smaller y
            order = np.argsort(at, kind="stable")
            edges.append(_Edges(vertical, floor_below, at[order], lo[order], hi[order], label[order]))
    return _Walls(tuple(edges), _Grid.of(grid))


def _normal_field(walls: np.ndarray, at: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel wall normal (x, y in the table frame) of the smoothed walls; `at`: only at these
    flat pixel indices (the gradient's norm and the division on the whole map were half its cost)."""
    solid = cv2.GaussianBlur((walls != Label.FLOOR).astype(np.float32), (0, 0), 6)
    gx = cv2.Sobel(solid, cv2.CV_32F, 1, 0, ksize=3)
    gy = -cv2.Sobel(solid, cv2.CV_32F, 0, 1, ksize=3)  # rows grow downward, y upward
    if at is not None:
        gx, gy = gx.ravel()[at], gy.ravel()[at]
    norm = np.maximum(np.hypot(gx, gy), 1e-6)
    return -gx / norm, -gy / norm


@dataclass(frozen=True, eq=False)
class _Normals:
    """The wall normals on the band along the walls, where the shading samples them (the pixel
    a ray enters, just past the edge it crosses); elsewhere (a camera inside a wall) the whole
    field is computed again, once for that frame."""

    band: np.ndarray  # (K,) int32 sorted flat pixel indices
    x: np.ndarray  # (K,) float32
    y: np.ndarray
    walls: _Grid

    @classmethod
    def of(cls, walls: np.ndarray) -> _Normals:
        solid = (walls != Label.FLOOR).astype(np.uint8)
        kernel = np.ones((2 * NORMAL_BAND_PX + 1, 2 * NORMAL_BAND_PX + 1), np.uint8)
        near = np.logical_and(cv2.dilate(solid, kernel), cv2.dilate(1 - solid, kernel))
        band = np.flatnonzero(near).astype(np.int32)
        return cls(band, *_normal_field(walls, band), _Grid.of(walls))

    def at(self, rows: np.ndarray, cols: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        flat = (rows * self.walls.shape[1] + cols).astype(np.int32)
        i = np.minimum(np.searchsorted(self.band, flat), self.band.size - 1)
        if not (self.band[i] == flat).all():
            nx, ny = _normal_field(self.walls.array())
            return nx[rows, cols], ny[rows, cols]
        return self.x[i], self.y[i]


@dataclass(frozen=True, eq=False)
class Scene:
    """What the camera needs of one maze, built once (`scene`, `cached_scene`)."""

    walls: _Walls
    normals: _Normals
    objects: _Walls  # the objects' footprints (maze.labels without the walls) as edges
    centroids: np.ndarray  # (N_LABELS, 2) each object's centre, metres, to shade it round
    reach: np.ndarray  # (N_LABELS,) metres from that centre to the footprint's farthest pixel (0: none)

    @classmethod
    def build(cls, maze: Maze) -> Scene:
        walls = np.ascontiguousarray(maze.walls, dtype=np.uint8)
        footprints = cv2.LUT(np.ascontiguousarray(maze.labels, dtype=np.uint8), _FOOTPRINT)
        centroids, reach = np.zeros((N_LABELS, 2)), np.zeros(N_LABELS)
        for name, (ox, oy) in maze.objects.items():
            label = Label[name.upper()]
            rows, cols = pixels_of(footprints, label)
            centroids[label] = ox, oy
            px_x, px_y = world_to_pixel(ox, oy)
            reach[label] = np.hypot((cols - px_x) / PX_PER_M_X, (rows - px_y) / PX_PER_M_Y).max() + 1 / PX_PER_M_X
        return cls(_walls(walls), _Normals.of(walls), _walls(footprints), centroids, reach)

    def arrays(self) -> dict[str, np.ndarray]:
        """Every array of the scene by a flat name (`load_scene` reads them back)."""
        out = {"centroids": self.centroids, "reach": self.reach}
        out |= {f"normals.{k}": getattr(self.normals, k) for k in ("band", "x", "y")}
        for part in ("walls", "objects"):
            walls: _Walls = getattr(self, part)
            grid = walls.grid
            out |= {f"{part}.shape": np.array(grid.shape), f"{part}.starts": grid.starts, f"{part}.values": grid.values}
            for i, edges in enumerate(walls.edges):
                out |= {f"{part}.{i}.{f.name}": np.asarray(getattr(edges, f.name)) for f in fields(_Edges)}
        return out

    @classmethod
    def from_arrays(cls, a: dict[str, np.ndarray]) -> Scene:
        parts = {}
        for part in ("walls", "objects"):
            grid = _Grid(tuple(int(v) for v in a[f"{part}.shape"]), a[f"{part}.starts"], a[f"{part}.values"])  # type: ignore[arg-type]
            edges = tuple(
                _Edges(
                    bool(a[f"{part}.{i}.vertical"]),
                    bool(a[f"{part}.{i}.floor_below"]),
                    *(a[f"{part}.{i}.{k}"] for k in ("at", "lo", "hi", "label")),
                )
                for i in range(4)
            )
            parts[part] = _Walls(edges, grid)
        normals = _Normals(a["normals.band"], a["normals.x"], a["normals.y"], parts["walls"].grid)
        return cls(parts["walls"], normals, parts["objects"], a["centroids"], a["reach"])


_scenes: weakref.WeakKeyDictionary[Maze, Scene] = weakref.WeakKeyDictionary()


def scene(maze: Maze) -> Scene:
    """The maze's scene, built once per maze object."""
    found = _scenes.get(maze)
    if found is None:
        found = _scenes[maze] = Scene.build(maze)
    return found


def _scene_path(content_hash: str, cache_dir: str | Path | None) -> Path:
    return default_cache_dir(cache_dir) / "scene" / f"{content_hash}-v{SCENE_CACHE_VERSION}{ARRAYS_SUFFIX}"


def load_scene(content_hash: str, cache_dir: str | Path | None = None) -> Scene | None:
    """The cached scene of the maze with these contents (`Maze.content_hash`), if one was saved."""
    try:
        return Scene.from_arrays(load_arrays(_scene_path(content_hash, cache_dir)))
    except (OSError, ValueError, KeyError):
        return None  # none yet, or torn or stale: built again by `cached_scene`


def cached_scene(maze: Maze, cache_dir: str | Path | None = None) -> Scene:
    """The maze's scene, read from the cache by its contents, or built and saved there."""
    found = _scenes.get(maze) or load_scene(maze.content_hash, cache_dir)
    if found is None:
        found = scene(maze)
        save_arrays(_scene_path(maze.content_hash, cache_dir), False, **found.arrays())
    _scenes[maze] = found
    return found


@dataclass(frozen=True)
class _Camera:
    width: int
    height: int
    focal: float  # pixels
    horizon: float  # row
    column_offsets: np.ndarray  # (W,) ray angle of each column relative to the heading
    background: np.ndarray  # (H, W) sky and floor, packed by `_pack`
    rows: np.ndarray  # (H, 1) int32 row index

    def buffers(self) -> tuple[np.ndarray, np.ndarray]:
        """This thread's (H, W) bool scratch and uint32 frame buffer: the server renders trials'
        frames in worker threads, so each thread paints into its own."""
        pool: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = _buffers.__dict__.setdefault("pool", {})
        mine = pool.get((self.width, self.height))
        if mine is None:
            mine = pool[(self.width, self.height)] = (
                np.empty((self.height, self.width), bool),
                np.empty((self.height, self.width), np.uint32),
            )
        return mine


_buffers = threading.local()


def _pack(bgr: np.ndarray) -> np.ndarray:
    """(..., 3) colours to (...) uint32 whose bytes are B, G, R, 0."""
    bgr = np.asarray(bgr)
    out = np.zeros(bgr.shape[:-1] + (4,), dtype=np.uint8)
    out[..., :3] = np.clip(np.rint(bgr), 0, 255)
    return out.view(np.uint32)[..., 0]


_cameras: dict[tuple[int, int], _Camera] = {}


def _camera(width: int, height: int) -> _Camera:
    camera = _cameras.get((width, height))
    if camera is None:
        focal = (width / 2) / np.tan(np.deg2rad(FOV_DEG / 2))
        horizon = HORIZON * height
        columns = np.arange(width) + 0.5
        offsets = np.arctan2(width / 2 - columns, focal)
        rows = np.arange(height) + 0.5
        sky = np.clip(rows / horizon, 0, 1)[:, None] ** 2
        sky_rgb = SKY_TOP + (SKY_HORIZON - SKY_TOP) * sky
        # Floor brightness by the distance that row looks at, so the table recedes.
        below = np.maximum(rows - horizon, 1e-3)
        floor_dist = focal * CAMERA_HEIGHT_M / below
        near = np.exp(-floor_dist / 0.6)[:, None]
        floor_rgb = FLOOR_FAR + (FLOOR_NEAR - FLOOR_FAR) * near
        column = np.where((rows < horizon)[:, None], sky_rgb, floor_rgb)
        background = _pack(np.repeat(column[:, None, :], width, axis=1))
        camera = _cameras[(width, height)] = _Camera(
            width, height, focal, horizon, offsets, background, np.arange(height, dtype=np.int32)[:, None]
        )
    return camera


def _cast_columns(
    walls: _Walls, cam: _Camera, x: float, y: float, theta: float, angles: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(labels, depth metres) of each column's ray on the walls grid, as `RayCaster.cast`
    gives them: only the edges facing the camera are met, each against the few columns
    its ends project to."""
    width = cam.width
    h, w = walls.grid.shape
    col, row = int(x * PX_PER_M_X + 0.5), int((h - 0.5) - y * PX_PER_M_Y)
    if not (0 <= col < w and 0 <= row < h):
        raise ValueError(f"camera ({x:.3f}, {y:.3f}) m is off the table")
    inside = int(walls.grid[row, col])
    if inside != Label.FLOOR:  # in a wall: it fills the view
        return np.full(width, inside, np.uint8), np.zeros(width)
    c, s = np.cos(theta), np.sin(theta)
    dx, dy = np.cos(angles), np.sin(angles)
    best = np.full(width, _NO_HIT)
    half, near = width / 2 - 0.5, 1e-6
    for edges in walls.edges:
        part = edges.facing(x, y)
        at, lo, hi = edges.at[part], edges.lo[part], edges.hi[part]
        # Ends relative to the camera, in its frame: z ahead, side to the left.
        if edges.vertical:
            fixed, oy, rd_fixed, rd_along = at - x, y, dx, dy
            za, zb = fixed * c + (lo - y) * s, fixed * c + (hi - y) * s
            sa, sb = -fixed * s + (lo - y) * c, -fixed * s + (hi - y) * c
        else:
            fixed, oy, rd_fixed, rd_along = at - y, x, dy, dx
            za, zb = (lo - x) * c + fixed * s, (hi - x) * c + fixed * s
            sa, sb = -(lo - x) * s + fixed * c, -(hi - x) * s + fixed * c
        with np.errstate(divide="ignore", invalid="ignore"):
            ja, jb = half - cam.focal * sa / za, half - cam.focal * sb / zb
        first = np.maximum(np.floor(np.minimum(ja, jb)) - 1, 0)
        last = np.minimum(np.ceil(np.maximum(ja, jb)) + 1, width - 1)
        crossing = (za <= near) | (zb <= near)  # an end behind the camera: any column may meet it
        first[crossing], last[crossing] = 0, width - 1
        keep = np.flatnonzero(((za > near) | (zb > near)) & (first <= last))
        first, counts = first[keep].astype(np.int64), last[keep].astype(np.int64) - first[keep].astype(np.int64) + 1
        seg = np.repeat(keep, counts)
        column = np.arange(seg.size) - np.repeat(np.cumsum(counts) - counts - first, counts)
        # Column ray against edge: t along the ray to the edge's line, then within its extent.
        with np.errstate(divide="ignore", invalid="ignore"):
            t = fixed[seg] / rd_fixed[column]
        along = oy + t * rd_along[column]
        hit = (t > 0) & (along >= lo[seg]) & (along <= hi[seg])
        # Nearest per column: positive float64 bits order as integers; the low 4 bits carry the label.
        key = np.where(hit, t, np.inf).view(np.int64) & ~15 | edges.label[part][seg]
        np.minimum.at(best, column, key)
    labels = (best & 15).astype(np.uint8)
    depth = (best & ~15).view(np.float64)
    missed = ~np.isfinite(depth)
    if missed.any():  # left the table: FLOOR, and the distance to its edge
        labels[missed] = Label.FLOOR
        depth[missed] = _to_edge(x, y, dx[missed], dy[missed], w, h)
    return labels, depth


def _to_edge(x: float, y: float, dx: np.ndarray, dy: np.ndarray, w: int, h: int) -> np.ndarray:
    """Metres from (x, y) along (dx, dy) to the raster's edge."""
    x_lo, x_hi = -0.5 / PX_PER_M_X, (w - 0.5) / PX_PER_M_X
    y_lo, y_hi = -0.5 / PX_PER_M_Y, (h - 0.5) / PX_PER_M_Y
    with np.errstate(divide="ignore"):
        tx = np.where(dx > 0, (x_hi - x) / dx, np.where(dx < 0, (x_lo - x) / dx, np.inf))
        ty = np.where(dy > 0, (y_hi - y) / dy, np.where(dy < 0, (y_lo - y) / dy, np.inf))
    return np.minimum(tx, ty)


def first_person(maze: Maze, x: float, y: float, theta: float, size: tuple[int, int] = (320, 240)) -> np.ndarray:
    """The Driver's camera at (x, y) metres facing `theta` radians: a (H, W, 3) BGR image."""
    return draw(scene(maze), x, y, theta, size)


def draw(scene: Scene, x: float, y: float, theta: float, size: tuple[int, int] = (320, 240)) -> np.ndarray:
    """`first_person` from the maze's scene."""
    width, height = int(size[0]), int(size[1])
    if width < 8 or height < 8:
        raise ValueError(f"image size {size!r} too small; expected at least 8x8 pixels")
    cam = _camera(width, height)
    angles = theta + cam.column_offsets
    labels, depth = _cast_columns(scene.walls, cam, x, y, theta, angles)
    z = np.maximum(depth * np.cos(cam.column_offsets), 1e-3)  # perpendicular: no fisheye
    wall = labels != Label.FLOOR

    # Lambert-like shading from the wall's normal just inside the wall entered, then fade with distance.
    inward = depth + 1e-4  # metres: the wall pixel entered, not the floor pixel before it
    col_px, row_px = world_to_pixel(x + inward * np.cos(angles), y + inward * np.sin(angles))
    h, w = scene.walls.grid.shape
    ci = np.clip(np.rint(col_px).astype(np.int64), 0, w - 1)
    ri = np.clip(np.rint(row_px).astype(np.int64), 0, h - 1)
    # Only the walls' columns are painted: their normals are the band's.
    normal_x, normal_y = scene.normals.at(ri[wall], ci[wall])
    facing = np.zeros(width)
    facing[wall] = np.abs(normal_x * np.cos(angles[wall]) + normal_y * np.sin(angles[wall]))
    # Edges where the wall changes colour or steps in depth, so corners read clearly.
    edge = np.zeros(width, dtype=bool)
    edge[1:] = (labels[1:] != labels[:-1]) | (np.abs(np.diff(z)) > 0.2 * z[1:])

    # Painted as packed 32-bit pixels into the camera's buffers: one select per pixel.
    mask, packed = cam.buffers()
    np.copyto(packed, cam.background)
    _paint_columns(packed, mask, cam, labels, z, WALL_HEIGHT_M, wall, facing, edge)
    paint_objects(packed, mask, scene, cam, x, y, theta, depth)
    return cv2.cvtColor(packed.view(np.uint8).reshape(height, width, 4), cv2.COLOR_BGRA2BGR)


# How tall each object stands, metres: a jar, a mug, a table-tennis paddle on its edge.
OBJECT_HEIGHT_M = np.zeros(N_LABELS)
OBJECT_HEIGHT_M[[Label.JAR, Label.MUG, Label.PADDLE]] = 0.14, 0.09, 0.17


def paint_objects(
    packed: np.ndarray,
    mask: np.ndarray,
    scene: Scene,
    cam: _Camera,
    x: float,
    y: float,
    theta: float,
    wall_depth: np.ndarray,
) -> None:
    """Paint the objects into a packed frame (`mask` is scratch): each column whose ray meets
    an object's footprint before any wall shows that object from the footprint's edge up to
    its height, shaded as a solid round its centre and by distance."""
    # Most frames show no object: cast only when a footprint's bounding circle has a column
    # in view whose wall is not nearer than the circle.
    for label in np.nonzero(scene.reach)[0]:
        cx, cy = scene.centroids[label]
        away, reach = float(np.hypot(cx - x, cy - y)), float(scene.reach[label])
        if away <= reach:
            break
        off = (np.arctan2(cy - y, cx - x) - theta + np.pi) % (2 * np.pi) - np.pi
        columns = np.abs(cam.column_offsets - off) <= np.arcsin(reach / away)
        if (wall_depth[columns] >= away - reach).any():
            break
    else:
        return
    angles = theta + cam.column_offsets
    labels, depth = _cast_columns(scene.objects, cam, x, y, theta, angles)
    seen = (labels != Label.FLOOR) & (depth <= wall_depth)  # level with a wall: the map says object
    if not seen.any():
        return
    z = np.maximum(depth * np.cos(cam.column_offsets), 1e-3)
    # The surface's normal points away from the object's centre.
    dx, dy = np.cos(angles), np.sin(angles)
    nx, ny = x + depth * dx - scene.centroids[labels, 0], y + depth * dy - scene.centroids[labels, 1]
    facing = np.abs(nx * dx + ny * dy) / np.maximum(np.hypot(nx, ny), 1e-6)
    facing[depth == 0] = 0.0  # the camera inside a footprint is up against the object, in its shadow
    edge = np.zeros(cam.width, dtype=bool)
    edge[1:] = seen[1:] != seen[:-1]
    _paint_columns(packed, mask, cam, labels, z, OBJECT_HEIGHT_M[labels], seen, facing, edge)


def _paint_columns(
    packed: np.ndarray,
    mask: np.ndarray,
    cam: _Camera,
    labels: np.ndarray,
    z: np.ndarray,
    height_m: float | np.ndarray,
    shown: np.ndarray,
    facing: np.ndarray,
    edge: np.ndarray,
) -> None:
    """Paint each `shown` column's solid (a wall, an object) from the floor up to `height_m` at
    perpendicular distance `z`, lit by how squarely it faces the ray and faded with distance,
    outlined along `edge` and its top (`mask` is scratch)."""
    top = np.clip(cam.horizon - cam.focal * (height_m - CAMERA_HEIGHT_M) / z, 0, cam.height)
    bottom = np.clip(cam.horizon + cam.focal * CAMERA_HEIGHT_M / z, 0, cam.height)
    top, bottom = np.where(shown, top, 0).astype(np.int32), np.where(shown, bottom, 0).astype(np.int32)
    light = (0.55 + 0.45 * facing) * FOG_M / (FOG_M + z)
    colour = PALETTE_BGR[labels].astype(np.float32) * light[:, None]
    colour[edge & shown] *= OUTLINE
    np.greater_equal(cam.rows, top, out=mask)
    np.logical_and(mask, cam.rows < bottom, out=mask)
    np.copyto(packed, _pack(colour), where=mask)
    cols = np.nonzero(shown & (bottom > top))[0]
    packed[top[cols], cols] = _pack(colour[cols] * OUTLINE)  # the top edge


def top_down(
    maze: Maze,
    pose: Sequence[float] | None = None,
    path: Sequence[Sequence[float]] | np.ndarray | None = None,
    rays: Literal[True] | tuple[np.ndarray, np.ndarray] | None = None,
    walls_only: bool = False,
    scale: float = 0.5,
) -> np.ndarray:
    """The maze seen from above, with the agent (an arrow at `pose` = (x, y, theta)), its
    `path` (a sequence of (x, y)) and its observation rays: `rays=True` casts them from the
    pose, or pass the (labels, depth) pair of `cast_rays` for that pose."""
    if scale <= 0:
        raise ValueError(f"scale must be positive, got {scale}")
    image = _map_image(maze, walls_only, scale).copy()
    s = 16

    def px(xy: ArrayLike) -> np.ndarray:
        c, r = world_to_pixel(*np.asarray(xy, dtype=np.float64).T)
        return np.stack([c * scale * s, r * scale * s], axis=-1).round().astype(np.int32)

    thick = max(int(round(3 * scale * 2)), 1)
    if path is not None and len(path) > 0:
        points = px(np.asarray(path, dtype=np.float64).reshape(-1, 2))
        cv2.polylines(image, [points.reshape(-1, 1, 2)], False, (40, 170, 255), thick, cv2.LINE_AA, 4)
        for p in points:
            cv2.circle(image, tuple(int(v) for v in p), max(thick, 2) * s, (40, 170, 255), -1, cv2.LINE_AA, 4)
    if pose is not None:
        x, y, theta = (float(v) for v in pose)
        if rays is True:
            rays = cast_rays(maze, x, y, theta)
        if rays is not None:
            labels, depth = (np.asarray(a) for a in rays)
            angles = theta + RAY_OFFSETS
            ends = px(np.stack([x + depth * np.cos(angles), y + depth * np.sin(angles)], axis=-1))
            start = tuple(int(v) for v in px((x, y)))
            for end, label in zip(ends, labels):
                cv2.line(image, start, tuple(int(v) for v in end), (150, 150, 150), 1, cv2.LINE_AA, 4)
                cv2.circle(
                    image,
                    tuple(int(v) for v in end),
                    max(thick, 2) * s,
                    LABEL_BGR[Label(int(label))] if label else (150, 150, 150),
                    -1,
                    cv2.LINE_AA,
                    4,
                )
        length = 0.09  # the arrow: a triangle a bit smaller than the robot
        tip = (x + length * np.cos(theta), y + length * np.sin(theta))
        back = [(x + 0.5 * length * np.cos(theta + a), y + 0.5 * length * np.sin(theta + a)) for a in (2.5, -2.5)]
        tri = px(np.array([tip, back[0], (x, y), back[1]]))
        cv2.fillPoly(image, [tri.reshape(-1, 1, 2)], (255, 255, 255), cv2.LINE_AA, 4)
        cv2.polylines(image, [tri.reshape(-1, 1, 2)], True, (30, 30, 30), max(thick // 2, 1), cv2.LINE_AA, 4)
    return image


_maps: weakref.WeakKeyDictionary[Maze, dict[tuple[bool, float], np.ndarray]] = weakref.WeakKeyDictionary()


def _map_image(maze: Maze, walls_only: bool, scale: float) -> np.ndarray:
    """The map in the benchmark's colours on a dark grey table, resized; cached per maze."""
    cache = _maps.setdefault(maze, {})
    key = (walls_only, round(scale, 4))
    if key not in cache:
        image = maze.image(walls_only=walls_only).copy()
        image[(maze.walls if walls_only else maze.labels) == Label.FLOOR] = (34, 34, 34)
        width = max(int(round(image.shape[1] * scale)), 1)
        height = max(int(round(image.shape[0] * scale)), 1)
        cache[key] = cv2.resize(image, (width, height), interpolation=cv2.INTER_AREA)
    return cache[key]

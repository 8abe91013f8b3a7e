"""Pictures of the simulated maze: the Driver's first-person camera and a top-down view.

The camera is a column ray caster: one ray per image column on the walls-only grid, each wall
column drawn with a height falling off with distance, shaded by how squarely the ray meets the
wall and by distance. The objects (jar, mug, paddle) are drawn as upright shapes at their
centroids, hidden behind nearer walls column by column.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import cv2
import numpy as np

from sim.geometry import world_to_pixel
from sim.labels import LABEL_BGR, PALETTE_BGR, Label
from sim.maze import Maze
from sim.observations import FOV_DEG, RAY_OFFSETS, RayCaster, cast_rays

# The camera: the paper's 78 degree field of view, low on the rover, looking level.
CAMERA_HEIGHT_M = 0.05
WALL_HEIGHT_M = 0.12
HORIZON = 0.42  # image row of the horizon, as a fraction of the height
FOG_M = 3.0  # distance at which colours have faded to half
RENDER_WINDOW = 32  # pixels per round: rays grazing a wall still advance quickly

# The room beyond the table, and the table top (BGR).
SKY_TOP, SKY_HORIZON = np.array([120, 104, 92.0]), np.array([200, 196, 190.0])
FLOOR_NEAR, FLOOR_FAR = np.array([58, 58, 62.0]), np.array([22, 22, 24.0])
OUTLINE = 0.45  # brightness of wall edges


@dataclass(frozen=True, eq=False)
class _Scene:
    """What the camera needs of one maze, built once."""
    walls: RayCaster
    normal_x: np.ndarray  # per-pixel wall normal, x (table frame)
    normal_y: np.ndarray
    objects: tuple[tuple[Label, float, float], ...]  # label, x, y (metres)


_scenes: "weakref.WeakKeyDictionary[Maze, _Scene]" = weakref.WeakKeyDictionary()


def _scene(maze: Maze) -> _Scene:
    scene = _scenes.get(maze)
    if scene is None:
        solid = cv2.GaussianBlur((maze.walls != Label.FLOOR).astype(np.float32), (0, 0), 6)
        gx = cv2.Sobel(solid, cv2.CV_32F, 1, 0, ksize=3)
        gy = -cv2.Sobel(solid, cv2.CV_32F, 0, 1, ksize=3)  # rows grow downward, y upward
        norm = np.maximum(np.hypot(gx, gy), 1e-6)
        objects = tuple((Label[name.upper()], x, y) for name, (x, y) in maze.objects.items())
        scene = _scenes[maze] = _Scene(RayCaster(maze.walls), -gx / norm, -gy / norm, objects)
    return scene


@dataclass(frozen=True)
class _Camera:
    width: int
    height: int
    focal: float  # pixels
    horizon: float  # row
    column_offsets: np.ndarray  # (W,) ray angle of each column relative to the heading
    background: np.ndarray  # (H, W) sky and floor, packed by `_pack`


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
        camera = _cameras[(width, height)] = _Camera(width, height, focal, horizon, offsets, background)
    return camera


def first_person(maze: Maze, x: float, y: float, theta: float, size=(320, 240)) -> np.ndarray:
    """The Driver's camera at (x, y) metres facing `theta` radians: a (H, W, 3) BGR image."""
    width, height = int(size[0]), int(size[1])
    if width < 8 or height < 8:
        raise ValueError(f"image size {size!r} too small; expected at least 8x8 pixels")
    scene, cam = _scene(maze), _camera(width, height)
    angles = theta + cam.column_offsets
    labels, depth = scene.walls.cast(x, y, angles, window=RENDER_WINDOW)
    z = np.maximum(depth * np.cos(cam.column_offsets), 1e-3)  # perpendicular: no fisheye
    wall = labels != Label.FLOOR

    top = np.clip(cam.horizon - cam.focal * (WALL_HEIGHT_M - CAMERA_HEIGHT_M) / z, 0, height)
    bottom = np.clip(cam.horizon + cam.focal * CAMERA_HEIGHT_M / z, 0, height)
    top, bottom = np.where(wall, top, 0).astype(np.int32), np.where(wall, bottom, 0).astype(np.int32)

    # Lambert-like shading from the wall's normal at the hit, then fade with distance.
    col_px, row_px = world_to_pixel(x + depth * np.cos(angles), y + depth * np.sin(angles))
    ci = np.clip(np.rint(col_px).astype(np.int64), 0, maze.walls.shape[1] - 1)
    ri = np.clip(np.rint(row_px).astype(np.int64), 0, maze.walls.shape[0] - 1)
    facing = np.abs(scene.normal_x[ri, ci] * np.cos(angles) + scene.normal_y[ri, ci] * np.sin(angles))
    light = (0.55 + 0.45 * facing) * FOG_M / (FOG_M + z)
    colour = PALETTE_BGR[labels].astype(np.float32) * light[:, None]
    # Edges where the wall changes colour or steps in depth, so corners read clearly.
    edge = np.zeros(width, dtype=bool)
    edge[1:] = (labels[1:] != labels[:-1]) | (np.abs(np.diff(z)) > 0.2 * z[1:])
    colour[edge & wall] *= OUTLINE

    # Painted as packed 32-bit pixels: one select per pixel instead of one per channel.
    rows = np.arange(height, dtype=np.int32)[:, None]
    mask = (rows >= top) & (rows < bottom)
    packed = np.where(mask, _pack(colour), cam.background)
    cols = np.nonzero(wall & (bottom > top))[0]
    packed[top[cols], cols] = _pack(colour[cols] * OUTLINE)  # the wall's top edge
    image = cv2.cvtColor(packed.view(np.uint8).reshape(height, width, 4), cv2.COLOR_BGRA2BGR)

    for label, ox, oy in scene.objects:
        _draw_object(image, cam, label, x, y, theta, ox, oy, z)
    return image


# Shapes per object, in metres: (width, height) of the body.
_OBJECT_SIZE = {Label.JAR: (0.10, 0.14), Label.MUG: (0.08, 0.08), Label.PADDLE: (0.15, 0.17)}


def _draw_object(image, cam: _Camera, label: Label, x, y, theta, ox, oy, wall_z) -> None:
    dx, dy = ox - x, oy - y
    z = dx * np.cos(theta) + dy * np.sin(theta)  # ahead of the camera
    side = -dx * np.sin(theta) + dy * np.cos(theta)  # to its left
    if z < 0.04:
        return
    scale = cam.focal / z  # pixels per metre at the object
    centre = cam.width / 2 - side * scale
    width_m, height_m = _OBJECT_SIZE[label]
    half = width_m / 2 * scale * (1.4 if label == Label.MUG else 1.0)  # room for the handle
    c0, c1 = int(np.floor(centre - half)) - 1, int(np.ceil(centre + half)) + 2
    c0, c1 = max(c0, 0), min(c1, cam.width)
    if c0 >= c1:
        return
    visible = wall_z[c0:c1] > z
    if not visible.any():
        return
    base = cam.horizon + CAMERA_HEIGHT_M * scale
    top = base - height_m * scale
    r0, r1 = max(int(np.floor(top)) - 2, 0), min(int(np.ceil(base)) + 2, cam.height)
    if r0 >= r1:
        return
    patch = image[r0:r1, c0:c1].copy()
    light = FOG_M / (FOG_M + z)
    bgr = tuple(float(v) * light for v in LABEL_BGR[label])
    dark = tuple(v * 0.55 for v in bgr)
    s = 16  # sub-pixel precision for cv2 drawing (4 fractional bits)

    def pt(u, v):  # metres right of the centre / above the floor -> patch pixels
        return (int(round((centre + u * scale - c0) * s)), int(round((base - v * scale - r0) * s)))

    def ax(a, b):
        return (max(int(round(a * scale * s)), 1), max(int(round(b * scale * s)), 1))

    w2 = width_m / 2
    if label == Label.PADDLE:  # a round blade on a handle
        cv2.rectangle(patch, pt(-0.012, 0.0), pt(0.012, 0.06), dark, -1, cv2.LINE_AA, 4)
        cv2.ellipse(patch, pt(0, 0.11), ax(w2, 0.06), 0, 0, 360, bgr, -1, cv2.LINE_AA, 4)
        cv2.ellipse(patch, pt(0, 0.11), ax(w2, 0.06), 0, 0, 360, dark, 1, cv2.LINE_AA, 4)
    else:  # a cylinder: body, rim ellipse; the jar has a lid, the mug a handle
        if label == Label.MUG:
            cv2.ellipse(patch, pt(w2, height_m * 0.5), ax(0.025, 0.025), 0, 0, 360, dark,
                        max(int(0.012 * scale), 1), cv2.LINE_AA, 4)
        cv2.rectangle(patch, pt(-w2, 0), pt(w2, height_m), bgr, -1, cv2.LINE_AA, 4)
        cv2.ellipse(patch, pt(0, 0), ax(w2, 0.012), 0, 0, 180, bgr, -1, cv2.LINE_AA, 4)
        cv2.ellipse(patch, pt(0, height_m), ax(w2, 0.012), 0, 0, 360, dark, -1, cv2.LINE_AA, 4)
        if label == Label.JAR:
            cv2.rectangle(patch, pt(-w2 * 0.85, height_m), pt(w2 * 0.85, height_m + 0.02),
                          dark, -1, cv2.LINE_AA, 4)
    region = image[r0:r1, c0:c1]
    region[:, visible] = patch[:, visible]


def top_down(maze: Maze, pose=None, path=None, rays=None, walls_only: bool = False,
             scale: float = 0.5) -> np.ndarray:
    """The maze seen from above, with the agent (an arrow at `pose` = (x, y, theta)), its
    `path` (a sequence of (x, y)) and its observation rays: `rays=True` casts them from the
    pose, or pass the (labels, depth) pair of `cast_rays` for that pose."""
    if scale <= 0:
        raise ValueError(f"scale must be positive, got {scale}")
    image = _map_image(maze, walls_only, scale).copy()
    s = 16

    def px(xy):
        c, r = world_to_pixel(*np.asarray(xy, dtype=np.float64).T)
        return np.stack([c * scale * s, r * scale * s], axis=-1).round().astype(np.int32)

    thick = max(int(round(3 * scale * 2)), 1)
    if path is not None and len(path) > 0:
        points = px(np.asarray(path, dtype=np.float64).reshape(-1, 2))
        cv2.polylines(image, [points.reshape(-1, 1, 2)], False, (40, 170, 255), thick, cv2.LINE_AA, 4)
        for p in points:
            cv2.circle(image, tuple(int(v) for v in p), max(thick, 2) * s, (40, 170, 255), -1,
                       cv2.LINE_AA, 4)
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
                cv2.circle(image, tuple(int(v) for v in end), max(thick, 2) * s,
                           LABEL_BGR[Label(int(label))] if label else (150, 150, 150), -1, cv2.LINE_AA, 4)
        length = 0.09  # the arrow: a triangle a bit smaller than the robot
        tip = (x + length * np.cos(theta), y + length * np.sin(theta))
        back = [(x + 0.5 * length * np.cos(theta + a), y + 0.5 * length * np.sin(theta + a))
                for a in (2.5, -2.5)]
        tri = px(np.array([tip, back[0], (x, y), back[1]]))
        cv2.fillPoly(image, [tri.reshape(-1, 1, 2)], (255, 255, 255), cv2.LINE_AA, 4)
        cv2.polylines(image, [tri.reshape(-1, 1, 2)], True, (30, 30, 30), max(thick // 2, 1),
                      cv2.LINE_AA, 4)
    return image


_maps: "weakref.WeakKeyDictionary[Maze, dict]" = weakref.WeakKeyDictionary()


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

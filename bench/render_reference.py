"""The first-person camera as it was before `sim.robot.render` cast columns against wall segments:
one grid march per column (`sim.core.observations.RayCaster`). Kept only as the yardstick that
`bench.sim` times the render against and `tests/sim/test_render.py` holds its pictures to."""

from __future__ import annotations

import weakref

import cv2
import numpy as np

from sim.core.geometry import world_to_pixel
from sim.core.labels import PALETTE_BGR, Label
from sim.core.maze import Maze
from sim.core.observations import RayCaster
from sim.robot.render import (
    CAMERA_HEIGHT_M,
    FOG_M,
    OUTLINE,
    WALL_HEIGHT_M,
    _camera,
    _normal_field,
    _pack,
    paint_objects,
    scene,
)

RENDER_WINDOW = 32
_casters: weakref.WeakKeyDictionary[Maze, RayCaster] = weakref.WeakKeyDictionary()
# The whole normal field: the march samples it on either side of a wall's edge, not only on the band.
_normals: weakref.WeakKeyDictionary[Maze, tuple[np.ndarray, np.ndarray]] = weakref.WeakKeyDictionary()


def first_person(maze: Maze, x: float, y: float, theta: float, size=(320, 240)) -> np.ndarray:
    width, height = int(size[0]), int(size[1])
    drawn, cam = scene(maze), _camera(width, height)
    caster = _casters.get(maze)
    if caster is None:
        caster = _casters[maze] = RayCaster(maze.walls)
    if maze not in _normals:
        _normals[maze] = _normal_field(maze.walls)
    normal_x, normal_y = _normals[maze]
    angles = theta + cam.column_offsets
    labels, depth = caster.cast(x, y, angles, window=RENDER_WINDOW)
    z = np.maximum(depth * np.cos(cam.column_offsets), 1e-3)
    wall = labels != Label.FLOOR
    top = np.clip(cam.horizon - cam.focal * (WALL_HEIGHT_M - CAMERA_HEIGHT_M) / z, 0, height)
    bottom = np.clip(cam.horizon + cam.focal * CAMERA_HEIGHT_M / z, 0, height)
    top, bottom = np.where(wall, top, 0).astype(np.int32), np.where(wall, bottom, 0).astype(np.int32)
    col_px, row_px = world_to_pixel(x + depth * np.cos(angles), y + depth * np.sin(angles))
    ci = np.clip(np.rint(col_px).astype(np.int64), 0, maze.walls.shape[1] - 1)
    ri = np.clip(np.rint(row_px).astype(np.int64), 0, maze.walls.shape[0] - 1)
    facing = np.abs(normal_x[ri, ci] * np.cos(angles) + normal_y[ri, ci] * np.sin(angles))
    light = (0.55 + 0.45 * facing) * FOG_M / (FOG_M + z)
    colour = PALETTE_BGR[labels].astype(np.float32) * light[:, None]
    edge = np.zeros(width, dtype=bool)
    edge[1:] = (labels[1:] != labels[:-1]) | (np.abs(np.diff(z)) > 0.2 * z[1:])
    colour[edge & wall] *= OUTLINE
    rows = np.arange(height, dtype=np.int32)[:, None]
    mask = (rows >= top) & (rows < bottom)
    packed = np.where(mask, _pack(colour), cam.background)
    cols = np.nonzero(wall & (bottom > top))[0]
    packed[top[cols], cols] = _pack(colour[cols] * OUTLINE)
    paint_objects(packed, np.empty(mask.shape, bool), drawn, cam, x, y, theta, depth)
    return cv2.cvtColor(packed.view(np.uint8).reshape(height, width, 4), cv2.COLOR_BGRA2BGR)

"""The maze as a `foxglove.SceneUpdate`: walls as coloured boxes, the targets as labelled pillars.

Walls are the `walls` raster pooled into 2 cm cells; each row's runs of wall cells of one colour
become one cube, so a benchmark maze is a few hundred primitives rather than a million pixels.
Everything is in the `table` frame (x right, y up, metres), standing on the table at z = 0.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from sim.core.geometry import MAP_HEIGHT_PX, MAP_WIDTH_PX, TABLE_HEIGHT_M, TABLE_WIDTH_M
from sim.core.labels import LABEL_BGR, WALL_LABELS, Label, object_label
from sim.core.maze import Maze

CELL_M = 0.02
WALL_HEIGHT_M = 0.10
TARGET_RADIUS_M = 0.05
TARGET_HEIGHT_M = 0.15
_IDENTITY = {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}


def colour(label: Label, alpha: float = 1.0) -> dict[str, float]:
    b, g, r = LABEL_BGR[label]
    return {"r": r / 255, "g": g / 255, "b": b / 255, "a": alpha}


def _pose(x: float, y: float, z: float) -> dict[str, Any]:
    return {"position": {"x": x, "y": y, "z": z}, "orientation": dict(_IDENTITY)}


def _entity(stamp: dict[str, Any], frame: str, entity_id: str, **primitives: list[dict[str, Any]]) -> dict[str, Any]:
    entity = {
        "timestamp": stamp,
        "frame_id": frame,
        "id": entity_id,
        "lifetime": {"sec": 0, "nsec": 0},
        "frame_locked": True,
        "metadata": [],
    }
    for kind in ("arrows", "cubes", "spheres", "cylinders", "lines", "triangles", "texts", "models"):
        entity[kind] = primitives.get(kind, [])
    return entity


def wall_cells(maze: Maze) -> np.ndarray:
    """(rows, cols) of cell labels: the most common wall label in each cell, FLOOR where none."""
    px_x, px_y = (MAP_WIDTH_PX - 1) / TABLE_WIDTH_M, (MAP_HEIGHT_PX - 1) / TABLE_HEIGHT_M
    cols, rows = math.ceil(TABLE_WIDTH_M / CELL_M), math.ceil(TABLE_HEIGHT_M / CELL_M)
    # Pixel -> cell (row 0 at y = 0, the table's bottom edge).
    cell_c = np.minimum((np.arange(maze.walls.shape[1]) / px_x / CELL_M).astype(int), cols - 1)
    cell_r = np.minimum(
        ((maze.walls.shape[0] - 1 - np.arange(maze.walls.shape[0])) / px_y / CELL_M).astype(int), rows - 1
    )
    counts = np.zeros((rows, cols, len(Label)), np.int32)
    r_idx, c_idx = np.nonzero(np.isin(maze.walls, WALL_LABELS))
    np.add.at(counts, (cell_r[r_idx], cell_c[c_idx], maze.walls[r_idx, c_idx]), 1)
    cells = counts.argmax(axis=2).astype(np.uint8)
    cells[counts.sum(axis=2) == 0] = Label.FLOOR
    cells_u8: np.ndarray = cells
    return cells_u8


def wall_cubes(maze: Maze) -> list[dict[str, Any]]:
    cells = wall_cells(maze)
    cubes = []
    for row, line in enumerate(cells):
        col = 0
        while col < len(line):
            label = line[col]
            end = col + 1
            while end < len(line) and line[end] == label:
                end += 1
            if label != Label.FLOOR:
                cubes.append(
                    {
                        "pose": _pose((col + end) / 2 * CELL_M, (row + 0.5) * CELL_M, WALL_HEIGHT_M / 2),
                        "size": {"x": (end - col) * CELL_M, "y": CELL_M, "z": WALL_HEIGHT_M},
                        "color": colour(Label(label)),
                    }
                )
            col = end
    return cubes


def scene_update(maze: Maze, targets: tuple[str, ...], stamp: dict[str, Any], frame: str) -> dict[str, Any]:
    """Walls and the trial's targets, numbered in the order the trial visits them."""
    entities = [_entity(stamp, frame, "maze/walls", cubes=wall_cubes(maze))]
    for order, target in enumerate(targets, start=1):
        x, y = maze.objects[target]
        label = object_label(target)
        entities.append(
            _entity(
                stamp,
                frame,
                f"target/{target}",
                cylinders=[
                    {
                        "pose": _pose(x, y, TARGET_HEIGHT_M / 2),
                        "size": {"x": 2 * TARGET_RADIUS_M, "y": 2 * TARGET_RADIUS_M, "z": TARGET_HEIGHT_M},
                        "bottom_scale": 1.0,
                        "top_scale": 1.0,
                        "color": colour(label),
                    }
                ],
                texts=[
                    {
                        "pose": _pose(x, y, TARGET_HEIGHT_M + 0.05),
                        "billboard": True,
                        "font_size": 14.0,
                        "scale_invariant": True,
                        "color": colour(Label.WHITE),
                        "text": f"{order}: {target}",
                    }
                ],
            )
        )
    return {"deletions": [], "entities": entities}

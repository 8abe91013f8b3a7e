"""The walls of the Commander's map as data a screen reader's words are made of
(`static/mapwords.js`): each connected piece of one colour is a straight wall (its two ends), a
bent one (where it spans) or the wall along the table's edge."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import cv2
import numpy as np

from sim.core.geometry import pixel_to_world
from sim.core.labels import WALL_LABELS
from sim.core.maze import Maze

MIN_LENGTH_PX = 30  # about 5 cm: a speck of colour, not a wall
STRAIGHT_FILL = 0.6  # a straight wall fills most of its tightest box; a bent one little of it
EDGE_SPAN = 0.95  # a piece spanning this share of the table both ways runs along its edge


class WallShape(StrEnum):
    STRAIGHT = "straight"
    BENT = "bent"
    EDGE = "edge"


@dataclass(frozen=True)
class Wall:
    colour: str
    shape: WallShape
    # straight: its two ends, west end first; bent: the box it spans (x0, y0) to (x1, y1); edge: the table's
    start: tuple[float, float]
    end: tuple[float, float]

    def as_json(self) -> dict[str, object]:
        return {"colour": self.colour, "shape": str(self.shape), "from": list(self.start), "to": list(self.end)}


def _metres(col: float, row: float) -> tuple[float, float]:
    x, y = pixel_to_world(col, row)
    return round(float(x), 2), round(float(y), 2)


def walls(maze: Maze) -> list[Wall]:
    """The maze's walls, by colour (in `WALL_LABELS`' order), then from west to east."""
    height, width = maze.walls.shape
    found: list[Wall] = []
    for label in WALL_LABELS:
        of_colour = []
        count, pieces, stats, _ = cv2.connectedComponentsWithStats(
            (maze.walls == label).astype(np.uint8), connectivity=8
        )
        for i in range(1, count):
            rows, cols = np.nonzero(pieces == i)
            (cx, cy), (w, h), angle = cv2.minAreaRect(np.column_stack([cols, rows]).astype(np.float32))
            if max(w, h) < MIN_LENGTH_PX:
                continue
            left, top, box_w, box_h = (int(stats[i, k]) for k in range(4))
            if box_w >= EDGE_SPAN * width and box_h >= EDGE_SPAN * height:
                of_colour.append(Wall(label.word, WallShape.EDGE, _metres(0, height - 1), _metres(width - 1, 0)))
            elif stats[i, cv2.CC_STAT_AREA] >= STRAIGHT_FILL * w * h:
                theta = np.deg2rad(angle if w >= h else angle + 90)
                half = max(w, h) / 2
                ends = sorted(
                    _metres(cx + sign * half * np.cos(theta), cy + sign * half * np.sin(theta)) for sign in (-1, 1)
                )
                of_colour.append(Wall(label.word, WallShape.STRAIGHT, ends[0], ends[1]))
            else:
                of_colour.append(
                    Wall(label.word, WallShape.BENT, _metres(left, top + box_h - 1), _metres(left + box_w - 1, top))
                )
        found += sorted(of_colour, key=lambda wall: wall.start)
    return found

"""Synthetic mazes whose ray answers are known exactly: rectangles of one label on a blank table."""

from __future__ import annotations

import cv2
import numpy as np

from sim.core.geometry import MAP_HEIGHT_PX, MAP_WIDTH_PX
from sim.core.labels import Label
from sim.core.maze import Maze

BORDER_PX = 10  # white table edge, columns/rows 0..9 and the last 10
# Objects parked in the bottom-left corner unless a test places them.
DEFAULT_OBJECTS = {Label.JAR: (100, 1000), Label.MUG: (200, 1000), Label.PADDLE: (300, 1000)}
OBJECT_RADIUS_PX = 40


def synthetic_maze(rects=(), objects=None, border: bool = True, name: str = "synthetic") -> Maze:
    """`rects`: (label, col0, row0, col1, row1) filled inclusive; `objects`: label -> (col, row)
    disc centres."""
    labels = np.zeros((MAP_HEIGHT_PX, MAP_WIDTH_PX), dtype=np.uint8)
    if border:
        labels[:BORDER_PX] = labels[-BORDER_PX:] = Label.WHITE
        labels[:, :BORDER_PX] = labels[:, -BORDER_PX:] = Label.WHITE
    for label, c0, r0, c1, r1 in rects:
        labels[r0 : r1 + 1, c0 : c1 + 1] = label
    for label, (col, row) in {**DEFAULT_OBJECTS, **(objects or {})}.items():
        cv2.circle(labels, (col, row), OBJECT_RADIUS_PX, int(label), -1)
    return Maze.from_labels(labels, name)

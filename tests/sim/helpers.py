"""Small synthetic mazes whose graphs and observations are known by hand."""

from __future__ import annotations

import numpy as np

from sim.core.geometry import MAP_HEIGHT_PX, MAP_WIDTH_PX, world_to_pixel
from sim.core.labels import Label


def open_table(objects=((0.5, 0.5), (1.2, 1.0), (2.0, 1.5))) -> np.ndarray:
    """An empty table with a red border and three 16-pixel object blobs at the given (x, y)."""
    labels = np.zeros((MAP_HEIGHT_PX, MAP_WIDTH_PX), dtype=np.uint8)
    labels[:8, :] = labels[-8:, :] = Label.RED
    labels[:, :8] = labels[:, -8:] = Label.RED
    for label, (x, y) in zip((Label.JAR, Label.MUG, Label.PADDLE), objects):
        c, r = (int(v) for v in world_to_pixel(x, y))
        labels[r - 8 : r + 8, c - 8 : c + 8] = label
    return labels


def wall_at_x(labels: np.ndarray, x: float, label: Label = Label.BLUE, y_range=(0.0, 2.06)) -> np.ndarray:
    """Add a vertical wall 10 pixels thick at table x, between the given y values."""
    c, _ = world_to_pixel(x, 0)
    _, r0 = world_to_pixel(0, y_range[1])
    _, r1 = world_to_pixel(0, y_range[0])
    labels[int(max(r0, 0)) : int(min(r1, MAP_HEIGHT_PX)), int(c) - 5 : int(c) + 5] = label
    return labels

"""The table frame and the benchmark's map raster.

Metres and radians; x to the right, y up, heading 0 along +x, counter-clockwise positive.
Maps are 1401 x 1175 pixel images of a 2.4638 m x 2.0574 m table, row 0 at the top.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

TABLE_WIDTH_M = 2.4638
TABLE_HEIGHT_M = 2.0574
MAP_WIDTH_PX = 1401
MAP_HEIGHT_PX = 1175
GRID_STEP_M = 0.07  # one forward move, and the navigation grid's spacing
HEADINGS = 8  # turns are 45 degrees
TURN_RAD = 2 * np.pi / HEADINGS
ROBOT_LENGTH_M = 0.254
SUCCESS_RADIUS_M = 2 * ROBOT_LENGTH_M  # 0.508 m: success threshold of the benchmark

# Unit steps on the grid per heading index (0 = +x, counter-clockwise).
HEADING_DI = np.array([1, 1, 0, -1, -1, -1, 0, 1], dtype=np.int64)
HEADING_DJ = np.array([0, 1, 1, 1, 0, -1, -1, -1], dtype=np.int64)


def world_to_pixel(x: ArrayLike, y: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Metres to (column, row) floats, as the benchmark maps them."""
    col = np.asarray(x, dtype=np.float64) / TABLE_WIDTH_M * (MAP_WIDTH_PX - 1)
    row = (1.0 - np.asarray(y, dtype=np.float64) / TABLE_HEIGHT_M) * (MAP_HEIGHT_PX - 1)
    return col, row


def pixel_to_world(col: ArrayLike, row: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(column, row) to metres: the inverse of `world_to_pixel`."""
    x = np.asarray(col, dtype=np.float64) / (MAP_WIDTH_PX - 1) * TABLE_WIDTH_M
    y = (1.0 - np.asarray(row, dtype=np.float64) / (MAP_HEIGHT_PX - 1)) * TABLE_HEIGHT_M
    return x, y


def heading_index(theta: float) -> int:
    """The nearest multiple of 45 degrees to `theta` (radians), as an index 0..7."""
    return int(np.round(float(theta) / TURN_RAD)) % HEADINGS


def wrap_angle(theta: float) -> float:
    """`theta` in (-pi, pi]: the one range headings are recorded in, simulator and rover alike."""
    return math.remainder(float(theta), 2 * math.pi)


def heading_angle(k: ArrayLike) -> NDArray[np.float64]:
    """Heading index (0..7) to radians in [0, 2 pi)."""
    angle: NDArray[np.float64] = np.asarray(k) % HEADINGS * TURN_RAD
    return angle

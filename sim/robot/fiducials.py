"""The ArUco markers of the overhead camera: where they are, and how they are found.

Four markers lie flat just outside the table's corners and fix the table frame; one lies on
the rover's top, centred over its pose point, its printed "up" along the rover's heading.
The renderer (`sim.robot.overhead`) and the tracker (`sim.robot.tracking`) share this one layout, and a
lab prints and places its markers to match it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TypedDict

import cv2
import numpy as np

from sim.core.geometry import TABLE_HEIGHT_M, TABLE_WIDTH_M

DICTIONARY = cv2.aruco.DICT_4X4_50


class MarkerLayoutJson(TypedDict, total=False):
    """A layout as a calibration file holds it; a key left out takes the default."""

    corner_ids: list[int]
    rover_id: int
    corner_size_m: float
    corner_gap_m: float
    rover_size_m: float
    rover_height_m: float


@dataclass(frozen=True)
class MarkerLayout:
    """Marker ids and sizes in metres (a marker's size is its black square, without the white
    margin a print needs around it)."""

    corner_ids: tuple[int, int, int, int] = (0, 1, 2, 3)  # at (0, 0), (W, 0), (W, H), (0, H)
    rover_id: int = 4
    corner_size_m: float = 0.15
    corner_gap_m: float = 0.02  # from the table's edges to the marker's, along x and y
    rover_size_m: float = 0.14
    rover_height_m: float = 0.09  # the rover's top above the table

    def corner_points(self, marker_id: int) -> np.ndarray:
        """(4, 2) table metres of a corner marker's corners, in ArUco's order (its printed
        top-left, top-right, bottom-right, bottom-left); printed up is the table's +y."""
        k = self.corner_ids.index(marker_id)
        reach = self.corner_gap_m + self.corner_size_m / 2
        cx = -reach if k in (0, 3) else TABLE_WIDTH_M + reach
        cy = -reach if k in (0, 1) else TABLE_HEIGHT_M + reach
        return square(cx, cy, np.pi / 2, self.corner_size_m)

    def to_json(self) -> MarkerLayoutJson:
        return {
            "corner_ids": list(self.corner_ids),
            "rover_id": self.rover_id,
            "corner_size_m": self.corner_size_m,
            "corner_gap_m": self.corner_gap_m,
            "rover_size_m": self.rover_size_m,
            "rover_height_m": self.rover_height_m,
        }

    @classmethod
    def from_json(cls, data: MarkerLayoutJson) -> MarkerLayout:
        default = cls()
        a, b, c, d = (int(i) for i in data.get("corner_ids", default.corner_ids))
        return cls(
            (a, b, c, d),
            int(data.get("rover_id", default.rover_id)),
            float(data.get("corner_size_m", default.corner_size_m)),
            float(data.get("corner_gap_m", default.corner_gap_m)),
            float(data.get("rover_size_m", default.rover_size_m)),
            float(data.get("rover_height_m", default.rover_height_m)),
        )


def square(cx: float, cy: float, up: float, size: float) -> np.ndarray:
    """(4, 2) corners, in ArUco's order, of a marker centred at (cx, cy) whose printed up points
    along angle `up` (radians, table frame)."""
    forward = np.array([np.cos(up), np.sin(up)]) * size / 2
    right = np.array([np.sin(up), -np.cos(up)]) * size / 2
    centre = np.array([cx, cy])
    return np.stack(
        [centre + forward - right, centre + forward + right, centre - forward + right, centre - forward - right]
    )


def marker_heading(corners: np.ndarray) -> float:
    """The printed up of a marker from its (4, 2) corners in the table frame, using all four
    edges: radians."""
    c = np.asarray(corners, dtype=np.float64)
    up = (c[0] - c[3]) + (c[1] - c[2])
    right = (c[1] - c[0]) + (c[2] - c[3])
    v = up + np.array([-right[1], right[0]])  # right turned a quarter counter-clockwise is up
    return float(np.arctan2(v[1], v[0]))


def marker_image(marker_id: int, cells_px: int = 16, margin_cells: int = 1) -> np.ndarray:
    """The printed marker as a grey image: its black square (6 x 6 cells) and a white margin."""
    dictionary = cv2.aruco.getPredefinedDictionary(DICTIONARY)
    side = (dictionary.markerSize + 2) * cells_px
    marker = cv2.aruco.generateImageMarker(dictionary, marker_id, side, borderBits=1)
    margin = margin_cells * cells_px
    return cv2.copyMakeBorder(marker, margin, margin, margin, margin, cv2.BORDER_CONSTANT, value=255)


def detector() -> cv2.aruco.ArucoDetector:
    """The detector both calibration and tracking use: sub-pixel corners, the markers' own
    dictionary."""
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    params.cornerRefinementWinSize = 3
    return cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(DICTIONARY), params)


def detect(detector_: cv2.aruco.ArucoDetector, image: np.ndarray) -> dict[int, list[np.ndarray]]:
    """Every marker of the dictionary in a BGR or grey image: id -> list of (4, 2) pixel corners."""
    grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    corners, ids, _ = detector_.detectMarkers(grey)
    found: dict[int, list[np.ndarray]] = {}
    for quad, marker_id in zip(corners, [] if ids is None else ids.ravel()):
        found.setdefault(int(marker_id), []).append(quad.reshape(4, 2).astype(np.float64))
    return found

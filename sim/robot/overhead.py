"""The overhead camera: the table seen from above at an angle, with its ArUco markers.

A pinhole camera (`OverheadCamera`) looks down at the table from beyond its lower edge. The
maze's map lies flat on the table; the corner markers lie flat beside it; the rover is a plate
at `MarkerLayout.rover_height_m` carrying its marker, so it is seen with the parallax a real
camera sees. Every planar thing is drawn through its exact plane-to-image homography,
supersampled and area-averaged; then the optics and sensor (`Imaging`): blur, exposure, noise.
Deterministic for a given seed.
"""

from __future__ import annotations

import weakref
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from sim.core.geometry import MAP_HEIGHT_PX, MAP_WIDTH_PX, ROBOT_LENGTH_M, TABLE_HEIGHT_M, TABLE_WIDTH_M
from sim.core.labels import Label
from sim.core.maze import Maze
from sim.robot.fiducials import MarkerLayout, marker_image

ROVER_WIDTH_M = 0.20
ROVER_BGR = (96, 84, 70)  # a blue-grey chassis
TABLE_BGR = (34, 34, 34)  # the table top, where the map has floor
ROOM_BGR = (92, 98, 104)  # the lab floor beyond the table
SUPERSAMPLE = 4  # sub-pixels per pixel side when drawing a plane


@dataclass(frozen=True)
class OverheadCamera:
    """A pinhole camera in the table frame (metres): at `position`, looking at `look_at`,
    `fov_deg` across the image's width, turned `roll_deg` about its axis. The default is a
    4:3 webcam on a boom 2.5 m above the table, just beyond its lower edge and a little
    off-centre, tilted 24 degrees from straight down: the table and its corner markers fill
    the picture."""

    width: int = 960
    height: int = 720
    fov_deg: float = 70.0
    position: tuple[float, float, float] = (1.10, -0.30, 2.50)
    look_at: tuple[float, float, float] = (1.23, 0.80, 0.0)
    roll_deg: float = 1.5

    @property
    def camera_matrix(self) -> np.ndarray:
        f = (self.width / 2) / np.tan(np.deg2rad(self.fov_deg) / 2)
        return np.array([[f, 0, (self.width - 1) / 2], [0, f, (self.height - 1) / 2], [0, 0, 1]])

    @property
    def rotation(self) -> np.ndarray:
        """Rows: the camera's right, down and forward axes in the table frame."""
        forward = np.subtract(self.look_at, self.position).astype(np.float64)
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, (0.0, 0.0, 1.0))
        right /= np.linalg.norm(right)
        down = np.cross(forward, right)
        a = np.deg2rad(self.roll_deg)
        right, down = np.cos(a) * right + np.sin(a) * down, -np.sin(a) * right + np.cos(a) * down
        return np.stack([right, down, forward])

    def plane_homography(self, z: float = 0.0) -> np.ndarray:
        """3x3: table metres (x, y) on the plane at height `z` -> image pixels."""
        r = self.rotation
        t = -r @ np.asarray(self.position, dtype=np.float64)
        homography: np.ndarray = self.camera_matrix @ np.column_stack([r[:, 0], r[:, 1], r[:, 2] * z + t])
        return homography


@dataclass(frozen=True)
class Imaging:
    """What the lens and sensor do to the picture: Gaussian blur (pixels), exposure (a gain on
    the scene's brightness; 1 is right, under 0.2 dark, over 3 burnt out) and noise (standard
    deviation in grey levels)."""

    blur_px: float = 0.8
    exposure: float = 1.0
    noise: float = 2.5


def render_overhead(
    maze: Maze,
    pose: np.ndarray | Sequence[float] | None = None,
    camera: OverheadCamera = OverheadCamera(),
    imaging: Imaging = Imaging(),
    layout: MarkerLayout = MarkerLayout(),
    seed: int = 0,
) -> np.ndarray:
    """The overhead camera's (H, W, 3) BGR image of the table, with the rover at `pose`
    (x, y, heading in metres and radians; None: no rover on the table)."""
    image = _table_image(maze, camera, layout).astype(np.float32)
    if pose is not None:
        x, y, theta = (float(v) for v in pose)
        plate, ppm = _rover_plate(layout)
        # Plate pixel (col, row) -> table metres: its columns run along the heading, its rows
        # to the rover's right; pixel centres at integers, the plate centred on the pose.
        c0, r0 = (plate.shape[1] - 1) / 2, (plate.shape[0] - 1) / 2
        cos, sin = np.cos(theta), np.sin(theta)
        to_table = np.array(
            [
                [cos / ppm, sin / ppm, x - (cos * c0 + sin * r0) / ppm],
                [sin / ppm, -cos / ppm, y - (sin * c0 - cos * r0) / ppm],
                [0, 0, 1],
            ]
        )
        _draw_plane(image, plate, camera.plane_homography(layout.rover_height_m) @ to_table)
    return _expose(image, imaging, seed)


_tables: weakref.WeakKeyDictionary[Maze, dict[tuple[OverheadCamera, MarkerLayout], np.ndarray]] = (
    weakref.WeakKeyDictionary()
)


def _table_image(maze: Maze, camera: OverheadCamera, layout: MarkerLayout) -> np.ndarray:
    """The room, the table with its map and the corner markers as the camera sees them (cached)."""
    cache = _tables.setdefault(maze, {})
    key = (camera, layout)
    if key not in cache:
        image = np.empty((camera.height, camera.width, 3), dtype=np.float32)
        image[:] = ROOM_BGR
        table = maze.image().copy()
        table[maze.labels == Label.FLOOR] = TABLE_BGR
        # Map pixel (col, row) -> table metres, as `sim.core.geometry.pixel_to_world`.
        sx, sy = TABLE_WIDTH_M / (MAP_WIDTH_PX - 1), TABLE_HEIGHT_M / (MAP_HEIGHT_PX - 1)
        to_table = np.array([[sx, 0, 0], [0, -sy, TABLE_HEIGHT_M], [0, 0, 1]])
        on_table = camera.plane_homography(0.0)
        _draw_plane(image, table, on_table @ to_table, supersample=2)  # the map is finer already
        for marker_id in layout.corner_ids:
            printed = marker_image(marker_id)
            _draw_plane(image, printed, on_table @ _marker_to_table(printed, layout.corner_points(marker_id)))
        cache[key] = image.clip(0, 255).astype(np.uint8)
        cache[key].setflags(write=False)
    table_image: np.ndarray = cache[key]
    return table_image


_plates: dict[MarkerLayout, tuple[np.ndarray, float]] = {}


def _rover_plate(layout: MarkerLayout) -> tuple[np.ndarray, float]:
    """The rover's top seen from above, heading to the right: a dark plate with the marker;
    and its pixels per metre."""
    if layout not in _plates:
        cells = 16
        printed = marker_image(layout.rover_id, cells)
        ppm = 6 * cells / layout.rover_size_m  # six cells across the black square
        h, w = int(round(ROVER_WIDTH_M * ppm / 2)) * 2, int(round(ROBOT_LENGTH_M * ppm / 2)) * 2
        plate = np.empty((h, w, 3), dtype=np.uint8)
        plate[:] = ROVER_BGR
        # Printed up along the heading (+columns): the print turned a quarter clockwise.
        turned = cv2.rotate(printed, cv2.ROTATE_90_CLOCKWISE)
        n = turned.shape[0]
        r, c = (h - n) // 2, (w - n) // 2
        plate[r : r + n, c : c + n] = turned[..., None]
        _plates[layout] = plate, ppm
    return _plates[layout]


def _marker_to_table(printed: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """Homography from a printed marker's pixels to the table, given its black square's corners."""
    margin = (printed.shape[0] - printed.shape[0] * 6 // 8) / 2  # one cell of eight across
    inner = printed.shape[0] - 2 * margin
    src = np.array([[0, 0], [inner, 0], [inner, inner], [0, inner]], dtype=np.float64) + margin - 0.5
    return cv2.getPerspectiveTransform(src.astype(np.float32), corners.astype(np.float32)).astype(np.float64)


def _draw_plane(image: np.ndarray, picture: np.ndarray, to_image: np.ndarray, supersample: int = SUPERSAMPLE) -> None:
    """Paint `picture` (grey or BGR) into the float image through the homography `to_image`
    (picture pixel -> image pixel), area-averaged over `supersample`^2 sub-pixels per pixel."""
    h, w = picture.shape[:2]
    outline = np.array([[-0.5, -0.5], [w - 0.5, -0.5], [w - 0.5, h - 0.5], [-0.5, h - 0.5]])
    corners = cv2.perspectiveTransform(outline.reshape(-1, 1, 2), to_image).reshape(-1, 2)
    x0, y0 = np.maximum(np.floor(corners.min(axis=0)).astype(int), 0)
    x1, y1 = np.minimum(np.ceil(corners.max(axis=0)).astype(int) + 1, (image.shape[1], image.shape[0]))
    if x0 >= x1 or y0 >= y1:
        return
    s = supersample
    # Sub-pixel (u, v) of the region -> image pixel ((u + 0.5) / s - 0.5 + x0, ...).
    fine = np.array([[1 / s, 0, x0 + 0.5 / s - 0.5], [0, 1 / s, y0 + 0.5 / s - 0.5], [0, 0, 1]])
    back = np.linalg.inv(to_image) @ fine  # region sub-pixel -> picture pixel
    size = ((x1 - x0) * s, (y1 - y0) * s)
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    colour = picture if picture.ndim == 3 else cv2.cvtColor(picture, cv2.COLOR_GRAY2BGR)
    warped = cv2.warpPerspective(
        colour.astype(np.float32), back, size, flags=flags, borderMode=cv2.BORDER_CONSTANT, borderValue=0
    )
    cover = cv2.warpPerspective(
        np.ones((h, w), np.float32), back, size, flags=flags, borderMode=cv2.BORDER_CONSTANT, borderValue=0
    )
    area = (x1 - x0, y1 - y0)
    warped = cv2.resize(warped, area, interpolation=cv2.INTER_AREA)
    cover = cv2.resize(cover, area, interpolation=cv2.INTER_AREA)[..., None]
    region = image[y0:y1, x0:x1]
    region *= 1 - cover
    region += warped


def _expose(image: np.ndarray, imaging: Imaging, seed: int) -> np.ndarray:
    if imaging.blur_px > 0:
        image = cv2.GaussianBlur(image, (0, 0), imaging.blur_px)
    image = image * np.float32(imaging.exposure)
    if imaging.noise > 0:
        rng = np.random.default_rng(seed)
        image += rng.standard_normal(image.shape, dtype=np.float32) * np.float32(imaging.noise)
    return np.clip(image + 0.5, 0, 255).astype(np.uint8)

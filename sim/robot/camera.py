"""The rover's front camera as a lens model over the first-person render, and its calibration file.

`first_person` is an ideal pinhole: 78 degrees across, level, 5 cm above the table, its horizon
at 42 % of the image height. A real webcam adds lens distortion, exposure and sensor noise, so
`capture` resamples that ideal view through a `FrontCamera`: for each pixel of the captured
image, undistort its position to a viewing direction and read the render there (rendered
`supersample` times larger and area-averaged, so edges fall between pixels as on a sensor).
The camera's focal length is chosen so that the captured image still spans exactly 78 degrees
along its principal row, the field of view of the paper's rover and of the 13 rays.

With barrel distortion (k1 < 0) the image corners look a little beyond the render's 78
degrees; those few pixels repeat the render's edge column. No ray looks there.

`CameraCalibration` is what a lab measures of its camera (intrinsics, distortion, height,
pitch) plus the colours of its walls and objects under its light; `save`/`load` keep it as JSON.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any, TypedDict

import cv2
import numpy as np
from numpy.typing import ArrayLike

from sim.core.labels import Label
from sim.core.maze import Maze
from sim.core.observations import FOV_DEG
from sim.robot.calibration import CalibrationError, load_json, save_json
from sim.robot.render import CAMERA_HEIGHT_M, HORIZON, first_person

CALIBRATION_VERSION = 1


@dataclass(frozen=True, eq=False)
class FrontCamera:
    """A webcam on the rover: resolution, radial distortion, exposure gain and sensor noise."""

    width: int = 640
    height: int = 480
    k1: float = -0.06  # radial distortion (OpenCV's model): mild barrel, like a cheap webcam
    k2: float = 0.01
    gain: float = 1.0  # exposure: scales the scene's brightness before the sensor clips it
    noise_std: float = 2.0  # sensor noise, in 8-bit levels
    supersample: int = 2  # the render is this many times larger than the sensor

    def __post_init__(self) -> None:
        if not (16 <= self.width <= 4096 and 16 <= self.height <= 4096):
            raise ValueError(f"camera size must be 16..4096 pixels a side, got {self.width}x{self.height}")
        if not (abs(self.k1) <= 0.3 and abs(self.k2) <= 0.1):
            raise ValueError(f"distortion k1={self.k1}, k2={self.k2} is not mild (|k1| <= 0.3, |k2| <= 0.1)")
        if not 0 < self.gain <= 10:
            raise ValueError(f"gain must be in (0, 10], got {self.gain}")
        if not 0 <= self.noise_std <= 100:
            raise ValueError(f"noise_std must be in [0, 100] levels, got {self.noise_std}")
        if self.supersample not in (1, 2, 3, 4):
            raise ValueError(f"supersample must be 1..4, got {self.supersample}")

    @property
    def hfov_rad(self) -> float:
        return math.radians(FOV_DEG)

    @property
    def focal_px(self) -> float:
        """fx = fy, such that the principal row spans the full field of view after distortion."""
        t = math.tan(self.hfov_rad / 2)
        return (self.width / 2) / (t * (1 + self.k1 * t**2 + self.k2 * t**4))

    def calibration(self, colours: dict[str, ColourClass] | None = None) -> CameraCalibration:
        """What a perfect checkerboard calibration of this camera would measure."""
        # (cx, cy) in OpenCV's convention (pixel centres at integers): the render's horizon row.
        cx, cy = (self.width - 1) / 2, HORIZON * self.height - 0.5
        return CameraCalibration(
            width=self.width,
            height=self.height,
            fx=self.focal_px,
            fy=self.focal_px,
            cx=cx,
            cy=cy,
            k1=self.k1,
            k2=self.k2,
            camera_height_m=CAMERA_HEIGHT_M,
            camera_pitch_rad=0.0,
            colours=dict(colours or {}),
        )

    @cached_property
    def _maps(self) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
        """For each supersampled sensor pixel, where it reads the render; and the render's size."""
        s = self.supersample
        w, h = self.width * s, self.height * s
        f = self.focal_px * s
        cx, cy = (w - 1) / 2, HORIZON * h - 0.5
        cols, rows = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
        undistorted = np.stack(undistort_normalized((cols - cx) / f, (rows - cy) / f, self.k1, self.k2), axis=-1)
        # The render: as wide as the sensor, tall enough for the rows the sensor reads.
        render_w = w
        render_f = (render_w / 2) / math.tan(self.hfov_rad / 2)
        # (+ half a pixel: the outermost sample is a pixel centre, its square reaches beyond)
        above = -undistorted[..., 1].min() * render_f + 0.5
        below = undistorted[..., 1].max() * render_f + 0.5
        render_h = int(math.ceil(max(above / HORIZON, below / (1 - HORIZON)) - 1e-6))
        map_x = ((render_w - 1) / 2 + render_f * undistorted[..., 0]).astype(np.float32)
        map_y = ((HORIZON * render_h - 0.5) + render_f * undistorted[..., 1]).astype(np.float32)
        map_a, map_b = cv2.convertMaps(map_x, map_y, cv2.CV_16SC2)  # fixed point: 2x faster remap
        return map_a, map_b, (render_w, render_h)

    def ideal(self, maze: Maze, x: float, y: float, theta: float) -> np.ndarray:
        """The scene through the lens, before exposure and noise: (height, width, 3) uint8 BGR."""
        map_a, map_b, render_size = self._maps
        scene = first_person(maze, x, y, theta, size=render_size)
        sensor = cv2.remap(scene, map_a, map_b, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        if self.supersample > 1:
            sensor = cv2.resize(sensor, (self.width, self.height), interpolation=cv2.INTER_AREA)
        return sensor


def capture(
    maze: Maze,
    x: float,
    y: float,
    theta: float,
    camera: FrontCamera | None = None,
    rng: np.random.Generator | int | None = None,
) -> np.ndarray:
    """One frame of the front camera at pose (x, y, theta): (height, width, 3) uint8 BGR.

    The same `rng` seed gives the same frame, byte for byte."""
    camera = camera or FrontCamera()
    rng = np.random.default_rng(rng)
    image = camera.ideal(maze, x, y, theta)
    if camera.gain == 1.0 and camera.noise_std == 0:
        return image
    # OpenCV's generator, seeded from `rng`, draws the noise five times faster than numpy's.
    noise = np.empty(image.shape, dtype=np.float32)
    cv2.setRNGSeed(int(rng.integers(2**31)))
    cv2.randn(noise, 0.0, float(camera.noise_std))  # type: ignore[call-overload]  # stubs want arrays; OpenCV takes scalars
    out = cv2.scaleAdd(image.astype(np.float32), float(camera.gain), noise)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def undistort_normalized(xd: ArrayLike, yd: ArrayLike, k1: float, k2: float) -> tuple[np.ndarray, np.ndarray]:
    """Invert the radial model x_d = x_u (1 + k1 r_u^2 + k2 r_u^4) by fixed-point iteration
    (it converges in a few steps for mild distortion); normalized coordinates in and out."""
    xn, yn = np.asarray(xd, dtype=np.float64), np.asarray(yd, dtype=np.float64)
    xu, yu = xn, yn
    for _ in range(30):
        r2 = xu * xu + yu * yu
        scale = 1 + k1 * r2 + k2 * r2 * r2
        xu, yu = xn / scale, yn / scale
    return xu, yu


# -- calibration file ---------------------------------------------------------------------------

# Colour classes of the calibration: the table top and the labels a ray can see.
COLOUR_CLASSES = ("floor",) + tuple(label.word for label in Label if label != Label.FLOOR)


class ColourClassJson(TypedDict):
    mean: list[float]
    cov: list[list[float]]


class Intrinsics(TypedDict):
    fx: float
    fy: float
    cx: float
    cy: float


class Distortion(TypedDict):
    k1: float
    k2: float


class CameraCalibrationFile(TypedDict):
    """A front camera's calibration file (`CameraCalibration.save`)."""

    version: int
    image_size: list[int]  # width, height
    intrinsics: Intrinsics
    distortion: Distortion
    camera_height_m: float
    camera_pitch_rad: float
    colours: dict[str, ColourClassJson]
    object_depth_offset_m: float


@dataclass(frozen=True)
class ColourClass:
    """One colour class under a lab's light, a Gaussian over `perception.colour_features`."""

    mean: tuple[float, ...]
    cov: tuple[tuple[float, ...], ...]

    def to_json(self) -> ColourClassJson:
        return {"mean": list(self.mean), "cov": [list(row) for row in self.cov]}

    @classmethod
    def from_json(cls, data: Any, where: str) -> ColourClass:
        try:
            mean = np.asarray(data["mean"], dtype=np.float64)
            cov = np.asarray(data["cov"], dtype=np.float64)
        except (KeyError, TypeError, ValueError):
            raise CalibrationError(f"{where}: needs 'mean' (3 numbers) and 'cov' (3x3)") from None
        if mean.shape != (3,) or cov.shape != (3, 3) or not (np.isfinite(mean).all() and np.isfinite(cov).all()):
            raise CalibrationError(f"{where}: needs 'mean' (3 numbers) and 'cov' (3x3)")
        if not np.allclose(cov, cov.T) or np.linalg.eigvalsh(cov).min() <= 0:
            raise CalibrationError(f"{where}: 'cov' must be symmetric positive definite")
        return cls(tuple(mean.tolist()), tuple(tuple(r) for r in cov.tolist()))


@dataclass(frozen=True)
class CameraCalibration:
    """A lab's front camera: pinhole intrinsics (OpenCV convention, pixels), radial distortion,
    height of the lens above the table (metres), pitch (radians, positive looks down), and the
    colour classes of its walls and objects (empty until `perception.calibrate_colours`)."""

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    k1: float = 0.0
    k2: float = 0.0
    camera_height_m: float = CAMERA_HEIGHT_M
    camera_pitch_rad: float = 0.0
    colours: dict[str, ColourClass] = field(default_factory=dict)
    # Added to the depth of a ray that meets an object: where the camera sees an object stand
    # and where its footprint on the map begins differ (by the object's half width, for the
    # simulator's upright drawings at the footprint's centre); learned with the colours.
    object_depth_offset_m: float = 0.0

    def __post_init__(self) -> None:
        if not (16 <= self.width <= 4096 and 16 <= self.height <= 4096):
            raise CalibrationError(f"image size must be 16..4096 pixels a side, got {self.width}x{self.height}")
        if not (self.fx > 0 and self.fy > 0):
            raise CalibrationError(f"focal lengths must be positive, got fx={self.fx}, fy={self.fy}")
        if not (0 < self.camera_height_m < 1):
            raise CalibrationError(f"camera_height_m must be in (0, 1) metres, got {self.camera_height_m}")
        if not abs(self.object_depth_offset_m) <= 0.5:
            raise CalibrationError(f"object_depth_offset_m must be within 0.5 m, got {self.object_depth_offset_m}")
        if not abs(self.camera_pitch_rad) < math.radians(60):
            raise CalibrationError(f"camera_pitch_rad must be within 60 degrees, got {self.camera_pitch_rad}")
        unknown = set(self.colours) - set(COLOUR_CLASSES)
        if unknown:
            raise CalibrationError(f"unknown colour classes {sorted(unknown)}; expected {', '.join(COLOUR_CLASSES)}")

    def with_colours(self, colours: dict[str, ColourClass], object_depth_offset_m: float = 0.0) -> CameraCalibration:
        return replace(self, colours=dict(colours), object_depth_offset_m=float(object_depth_offset_m))

    def to_json(self) -> CameraCalibrationFile:
        return {
            "version": CALIBRATION_VERSION,
            "image_size": [self.width, self.height],
            "intrinsics": {"fx": self.fx, "fy": self.fy, "cx": self.cx, "cy": self.cy},
            "distortion": {"k1": self.k1, "k2": self.k2},
            "camera_height_m": self.camera_height_m,
            "camera_pitch_rad": self.camera_pitch_rad,
            "colours": {name: c.to_json() for name, c in sorted(self.colours.items())},
            "object_depth_offset_m": self.object_depth_offset_m,
        }

    @classmethod
    def from_json(cls, data: Any, where: str = "calibration") -> CameraCalibration:
        if not isinstance(data, dict):
            raise CalibrationError(f"{where}: expected a JSON object")
        if data.get("version") != CALIBRATION_VERSION:
            raise CalibrationError(f"{where}: version {data.get('version')!r}, expected {CALIBRATION_VERSION}")
        try:
            width, height = (int(v) for v in data["image_size"])
            intr, dist = data["intrinsics"], data["distortion"]
            colours = data.get("colours", {})
            if not isinstance(colours, dict):
                raise TypeError
            return cls(
                width=width,
                height=height,
                fx=float(intr["fx"]),
                fy=float(intr["fy"]),
                cx=float(intr["cx"]),
                cy=float(intr["cy"]),
                k1=float(dist["k1"]),
                k2=float(dist["k2"]),
                camera_height_m=float(data["camera_height_m"]),
                camera_pitch_rad=float(data["camera_pitch_rad"]),
                colours={name: ColourClass.from_json(c, f"{where}: colours.{name}") for name, c in colours.items()},
                object_depth_offset_m=float(data.get("object_depth_offset_m", 0.0)),
            )
        except CalibrationError:
            raise
        except (KeyError, TypeError, ValueError) as exc:
            raise CalibrationError(f"{where}: missing or malformed field ({exc!r})") from None

    def save(self, path: str | Path) -> Path:
        return save_json(self.to_json(), path)

    @classmethod
    def load(cls, path: str | Path) -> CameraCalibration:
        return cls.from_json(load_json(path, "a camera calibration"), str(path))

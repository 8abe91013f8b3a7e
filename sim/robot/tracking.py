"""Ground truth from the overhead camera: the rover's table pose from its ArUco marker.

`calibrate(image)` measures the table -> image homography from the four corner markers and
the camera's focal length from that homography (or takes it from a known field of view); the
result, `OverheadCalibration`, is saved as JSON. `OverheadTracker.update(frame, t_ns)` finds
the rover's marker, maps its corners onto the plane of the rover's top (so the marker's height
causes no parallax error), and returns a `TrackedPose`, or None whenever it cannot be sure:
no marker, a marker that is not the right square (partly hidden, misread), two candidates, or
a jump no rover can make between two frames. A pose is never guessed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict

import cv2
import numpy as np
from numpy.typing import ArrayLike
from tqdm import tqdm

from robot_client.camera import CameraSettings
from sim.robot import fiducials
from sim.robot.calibration import CalibrationError, load_json, save_json
from sim.robot.fiducials import MarkerLayout, MarkerLayoutJson
from sim.robot.frames import decode_jpeg
from sim.robot.overhead import render_overhead

if TYPE_CHECKING:
    from sim.core.maze import Maze

CALIBRATION_VERSION = 1
MAX_REPROJECTION_PX = 3.0  # corner markers fitting worse than this are not where the layout says


@dataclass(frozen=True)
class TrackedPose:
    x: float  # metres, table frame
    y: float
    heading: float  # radians, (-pi, pi], counter-clockwise from +x
    t_ns: int  # the frame's time, as given to `update`
    quality: float  # (0, 1]: how exactly the marker seen is the marker printed


class OverheadCalibrationFile(TypedDict):
    """The overhead camera's calibration file (`OverheadCalibration.save`)."""

    version: int
    image_size: list[int]  # width, height
    homography: list[list[float]]  # table metres -> pixels
    camera_matrix: list[list[float]]
    layout: MarkerLayoutJson
    reprojection_px: float


@dataclass(frozen=True, eq=False)
class OverheadCalibration:
    homography: np.ndarray  # 3x3: table metres (z = 0) -> image pixels
    camera_matrix: np.ndarray  # 3x3 intrinsics (focal length measured or from the field of view)
    image_size: tuple[int, int]  # width, height of the frames it holds for
    layout: MarkerLayout = field(default_factory=MarkerLayout)
    reprojection_px: float = 0.0  # RMS of the corner markers' corners under `homography`

    def plane_homography(self, z: float) -> np.ndarray:
        """3x3: table metres on the plane at height `z` -> image pixels. With H ~ K [r1 r2 t],
        the plane at z is K [r1 r2 t + z r3]."""
        m = np.linalg.solve(self.camera_matrix, self.homography)
        scale = (np.linalg.norm(m[:, 0]) + np.linalg.norm(m[:, 1])) / 2
        if m[2, 2] < 0:  # the table lies in front of the camera
            scale = -scale
        r3 = np.cross(m[:, 0], m[:, 1]) / scale**2  # unit length, towards the camera side
        out = self.homography.copy()
        out[:, 2] += z * scale * (self.camera_matrix @ r3)
        return out

    def fits(self, found: dict[int, list[np.ndarray]]) -> float | None:
        """Median pixel distance of the visible corner markers from where this calibration puts
        them; None when no corner marker is visible."""
        errors = [
            np.linalg.norm(_apply(self.homography, self.layout.corner_points(i)) - quads[0], axis=1)
            for i in self.layout.corner_ids
            for quads in [found.get(i)]
            if quads
        ]
        return float(np.median(np.concatenate(errors))) if errors else None

    # -- JSON ---------------------------------------------------------------------
    def to_json(self) -> OverheadCalibrationFile:
        return {
            "version": CALIBRATION_VERSION,
            "image_size": list(self.image_size),
            "homography": self.homography.tolist(),
            "camera_matrix": self.camera_matrix.tolist(),
            "layout": self.layout.to_json(),
            "reprojection_px": self.reprojection_px,
        }

    @classmethod
    def from_json(cls, data: Any, source: str = "calibration") -> OverheadCalibration:
        try:
            if data.get("version") != CALIBRATION_VERSION:
                raise CalibrationError(f"{source}: version {data.get('version')!r}, expected {CALIBRATION_VERSION}")
            h = np.array(data["homography"], dtype=np.float64)
            k = np.array(data["camera_matrix"], dtype=np.float64)
            width, height = (int(v) for v in data["image_size"])
            layout = MarkerLayout.from_json(data["layout"])
            reprojection = float(data["reprojection_px"])
        except CalibrationError:
            raise
        except (AttributeError, KeyError, TypeError, ValueError) as err:
            raise CalibrationError(f"{source}: not an overhead calibration ({type(err).__name__}: {err})") from None
        if h.shape != (3, 3) or k.shape != (3, 3) or not (np.isfinite(h).all() and np.isfinite(k).all()):
            raise CalibrationError(f"{source}: homography and camera_matrix must be finite 3x3 matrices")
        if abs(np.linalg.det(h)) < 1e-12 or k[0, 0] <= 0 or k[1, 1] <= 0 or width <= 0 or height <= 0:
            raise CalibrationError(f"{source}: singular homography, or a non-positive focal length or image size")
        return cls(h, k, (width, height), layout, reprojection)

    def save(self, path: str | Path) -> Path:
        return save_json(self.to_json(), path)

    @classmethod
    def load(cls, path: str | Path) -> OverheadCalibration:
        return cls.from_json(load_json(path, "an overhead calibration"), source=str(path))


def calibrate(image: np.ndarray, fov_deg: float | None = None) -> OverheadCalibration:
    """The calibration from one BGR image showing the four corner markers. The focal length is
    measured from the homography (square pixels, principal point at the centre) unless the
    camera's horizontal field of view `fov_deg` is given."""
    return _calibrate(image, fiducials.detect(fiducials.detector(), image), fov_deg, MarkerLayout(), None)


def _calibrate(
    image: np.ndarray,
    found: dict[int, list[np.ndarray]],
    fov_deg: float | None,
    layout: MarkerLayout,
    camera_matrix: np.ndarray | None,
) -> OverheadCalibration:
    height, width = image.shape[:2]
    missing = [i for i in layout.corner_ids if len(found.get(i, ())) != 1]
    if missing:
        raise CalibrationError(
            f"corner markers {missing} not seen exactly once (all of ids {list(layout.corner_ids)} must be in view)"
        )
    table = np.concatenate([layout.corner_points(i) for i in layout.corner_ids])
    pixels = np.concatenate([found[i][0] for i in layout.corner_ids])
    homography, _ = cv2.findHomography(table, pixels, 0)
    if homography is None:
        raise CalibrationError("the corner markers give no homography (are they in a line?)")
    rms = float(np.sqrt(np.mean(np.sum((_apply(homography, table) - pixels) ** 2, axis=1))))
    if rms > MAX_REPROJECTION_PX:
        raise CalibrationError(
            f"the corner markers are {rms:.1f} px (RMS) from any table plane; are they placed as the layout says?"
        )
    if camera_matrix is None:
        cx, cy = (width - 1) / 2, (height - 1) / 2
        if fov_deg is not None:
            if not 1 <= fov_deg <= 170:
                raise CalibrationError(f"field of view {fov_deg} degrees is not between 1 and 170")
            focal = (width / 2) / math.tan(math.radians(fov_deg) / 2)
        else:
            focal = _focal_length(homography, cx, cy)
            fov = math.degrees(2 * math.atan(width / 2 / focal)) if focal else None
            if fov is None or not 20 <= fov <= 150:
                raise CalibrationError(
                    "the focal length cannot be measured from this view (the camera "
                    "looks too squarely down); give the camera's field of view"
                )
        camera_matrix = np.array([[focal, 0, cx], [0, focal, cy], [0, 0, 1]])
    return OverheadCalibration(
        homography / homography[2, 2], np.asarray(camera_matrix, dtype=np.float64), (width, height), layout, rms
    )


def _focal_length(homography: np.ndarray, cx: float, cy: float) -> float | None:
    """The focal length making the table's x and y axes orthogonal and equally long (Zhang's two
    constraints with a known principal point), by least squares in 1/f^2; None if none fits."""
    h = np.linalg.solve(np.array([[1, 0, cx], [0, 1, cy], [0, 0, 1.0]]), homography)
    h1, h2 = h[:, 0], h[:, 1]
    a = np.array([h1[0] * h2[0] + h1[1] * h2[1], h1[0] ** 2 + h1[1] ** 2 - h2[0] ** 2 - h2[1] ** 2])
    b = np.array([h1[2] * h2[2], h1[2] ** 2 - h2[2] ** 2])
    denominator = float(a @ a)
    inverse_f2 = -float(a @ b) / denominator if denominator > 0 else 0.0
    return 1 / math.sqrt(inverse_f2) if inverse_f2 > 0 else None


def _apply(homography: np.ndarray, points: np.ndarray) -> np.ndarray:
    return cv2.perspectiveTransform(np.asarray(points, dtype=np.float64).reshape(-1, 1, 2), homography).reshape(-1, 2)


def _angle(a: float) -> float:
    """An angle in (-pi, pi]."""
    return math.pi - (math.pi - a) % (2 * math.pi)


@dataclass(frozen=True)
class TrackerConfig:
    max_speed_m_s: float = 0.6  # the rover does about 0.2 m/s; anything much faster is a misreading
    max_turn_rad_s: float = 4.0  # a 45 degree turn takes about 0.4 s
    jump_slack_m: float = 0.03  # allowed beyond max speed, for the noise of two measurements
    jump_slack_rad: float = math.radians(10)
    reacquire_frames: int = 3  # this many consistent frames elsewhere: the rover was moved (by hand)
    shape_tolerance: float = 0.12  # relative error of the marker's sides and diagonals accepted
    still_radius_m: float = 0.006  # measurements this close to the running mean are averaged
    still_heading_rad: float = math.radians(1.5)
    window: int = 8  # at most this many still measurements averaged
    stale_px: float = 4.0  # corner markers this far from where the calibration puts them: the camera moved


class OverheadTracker:
    """Overhead frames in, rover poses out, one frame at a time (frames in time order).

    Without a calibration, the first frame showing all four corner markers calibrates the
    tracker (measuring the focal length). Each frame that shows corner markers checks the
    calibration: if the camera has moved, the frame recalibrates it (keeping the camera's
    intrinsics) when it shows all four, and gives no pose otherwise.
    """

    def __init__(self, calibration: OverheadCalibration | None = None, config: TrackerConfig = TrackerConfig()):
        self.calibration = calibration
        self.layout = calibration.layout if calibration else MarkerLayout()
        self.config = config
        self._detector = fiducials.detector()
        self._plane: np.ndarray | None = None  # image -> rover-top plane, for `calibration`
        self._last: TrackedPose | None = None  # the last accepted measurement
        self._candidates: list[TrackedPose] = []  # consistent rejected ones, for re-acquiring
        self._still: list[TrackedPose] = []  # the current run of still measurements

    def update(self, frame: bytes | np.ndarray, t_ns: int) -> TrackedPose | None:
        """The rover's pose in this frame (JPEG bytes or a BGR image), or None."""
        image = decode_jpeg(frame) if not isinstance(frame, np.ndarray) else frame
        if self._last is not None and t_ns <= self._last.t_ns:
            raise ValueError(f"frame time {t_ns} ns is not after the previous frame's {self._last.t_ns} ns")
        found = fiducials.detect(self._detector, image)
        if not self._calibrated(image, found):
            return None
        measurement = self._measure(found.get(self.layout.rover_id, []), t_ns)
        if measurement is None or not self._plausible(measurement):
            return None
        return self._smoothed(measurement)

    # -- steps of `update` --------------------------------------------------------
    def _calibrated(self, image: np.ndarray, found: dict[int, list[np.ndarray]]) -> bool:
        calibration = self.calibration
        if calibration is not None:
            if tuple(calibration.image_size) != (image.shape[1], image.shape[0]):
                raise CalibrationError(
                    f"calibration is for {calibration.image_size[0]}x{calibration.image_size[1]} "
                    f"frames, this frame is {image.shape[1]}x{image.shape[0]}"
                )
            error = calibration.fits(found)
            if error is None or error <= self.config.stale_px:
                if self._plane is None:
                    self._plane = np.linalg.inv(calibration.plane_homography(self.layout.rover_height_m))
                return True
        try:  # no calibration yet, or the camera moved
            keep = None if calibration is None else calibration.camera_matrix
            self.calibration = _calibrate(image, found, None, self.layout, keep)
        except CalibrationError:
            return False
        self._plane = np.linalg.inv(self.calibration.plane_homography(self.layout.rover_height_m))
        return True

    def _measure(self, quads: list[np.ndarray], t_ns: int) -> TrackedPose | None:
        """The rover's marker mapped onto its plane; None unless exactly one marker seen is a
        square of the printed size (or exactly one is, near the last pose)."""
        assert self._plane is not None  # set by `_calibrated`, which comes first
        measurements = []
        for quad in quads:
            corners = _apply(self._plane, quad)
            sides = np.linalg.norm(corners - np.roll(corners, -1, axis=0), axis=1)
            diagonals = np.linalg.norm(corners[:2] - corners[2:], axis=1)
            size = self.layout.rover_size_m
            error = max(np.max(np.abs(sides / size - 1)), np.max(np.abs(diagonals / (size * math.sqrt(2)) - 1)))
            if error <= self.config.shape_tolerance:
                x, y = corners.mean(axis=0)
                measurements.append(
                    TrackedPose(
                        float(x),
                        float(y),
                        fiducials.marker_heading(corners),
                        t_ns,
                        float(1 - error / self.config.shape_tolerance),
                    )
                )
        if len(measurements) > 1 and self._last is not None:
            measurements = [m for m in measurements if self._reachable(self._last, m)]
        return measurements[0] if len(measurements) == 1 else None

    def _reachable(self, a: TrackedPose, b: TrackedPose) -> bool:
        dt = (b.t_ns - a.t_ns) * 1e-9
        c = self.config
        return (
            math.hypot(b.x - a.x, b.y - a.y) <= c.max_speed_m_s * dt + c.jump_slack_m
            and abs(_angle(b.heading - a.heading)) <= c.max_turn_rad_s * dt + c.jump_slack_rad
        )

    def _plausible(self, m: TrackedPose) -> bool:
        """Accept `m` if the rover could have got there since the last accepted pose; a run of
        `reacquire_frames` measurements consistent with each other but not with the track
        restarts it (the rover was carried, or the first pose was wrong)."""
        if self._last is None or self._reachable(self._last, m):
            self._last, self._candidates = m, []
            return True
        if self._candidates and not self._reachable(self._candidates[-1], m):
            self._candidates = []
        self._candidates.append(m)
        if len(self._candidates) < self.config.reacquire_frames:
            return False
        self._last, self._candidates, self._still = m, [], []
        return True

    def _smoothed(self, m: TrackedPose) -> TrackedPose:
        """The mean of the current run of still measurements: a standing rover's pose is averaged
        over up to `window` frames, a moving one's is the measurement itself (no lag)."""
        still = self._still
        if still:
            mx, my, mh = _mean(still)
            if (
                math.hypot(m.x - mx, m.y - my) > self.config.still_radius_m
                or abs(_angle(m.heading - mh)) > self.config.still_heading_rad
            ):
                still.clear()
        still.append(m)
        del still[: -self.config.window]
        x, y, heading = _mean(still)
        return TrackedPose(x, y, heading, m.t_ns, m.quality)


def _mean(ms: list[TrackedPose]) -> tuple[float, float, float]:
    heading = math.atan2(sum(math.sin(m.heading) for m in ms), sum(math.cos(m.heading) for m in ms))
    return sum(m.x for m in ms) / len(ms), sum(m.y for m in ms) / len(ms), heading


class TrackerScores(TypedDict):
    pos_err_median_m: float
    pos_err_p95_m: float
    heading_err_median_deg: float
    tracked_fraction: float  # of the frames, those that gave a pose


def evaluate_tracker(
    maze: Maze,
    poses: ArrayLike,
    seed: int = 0,
    fps: float = 5.0,
    progress: bool = False,
) -> TrackerScores:
    """The tracker against known truth: each of `poses` ((x, y, heading), one per frame at
    `fps`) rendered by the overhead camera, sent as a JPEG of the rover client's quality as the
    server receives it, tracked after a calibration from a JPEG of the empty table. Errors are over
    the frames that gave a pose; `tracked_fraction` says how many did."""
    rng = np.random.default_rng(seed)

    def jpeg(pose: np.ndarray | None) -> bytes:
        image = render_overhead(maze, pose, seed=int(rng.integers(2**31)))
        ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, CameraSettings().quality])
        return data.tobytes()

    tracker = OverheadTracker(calibrate(decode_jpeg(jpeg(None))))
    truths = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    position, heading = [], []
    for i, truth in enumerate(tqdm(truths, desc="overhead frames", unit="frame", disable=not progress)):
        pose = tracker.update(jpeg(truth), int(i * 1e9 / fps))
        if pose is not None:
            position.append(math.hypot(pose.x - truth[0], pose.y - truth[1]))
            heading.append(abs(math.degrees(_angle(pose.heading - truth[2]))))
    if not position:
        raise ValueError(f"the tracker gave no pose on any of {len(truths)} frames")
    return {
        "pos_err_median_m": float(np.median(position)),
        "pos_err_p95_m": float(np.percentile(position, 95)),
        "heading_err_median_deg": float(np.median(heading)),
        "tracked_fraction": len(position) / len(truths),
    }

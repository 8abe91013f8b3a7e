"""The front camera's lens model, and its calibration file."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from sim.robot.camera import CalibrationError, CameraCalibration, ColourClass, FrontCamera, capture
from sim.robot.render import first_person
from sim.tasks.library import MazeLibrary


@pytest.fixture(scope="module")
def maze():
    return MazeLibrary().load("gen-000")


POSE = (0.6, 0.5, 0.4)


def test_capture_is_deterministic_per_seed(maze):
    camera = FrontCamera(320, 240)
    a, b = capture(maze, *POSE, camera, rng=7), capture(maze, *POSE, camera, rng=7)
    assert a.shape == (240, 320, 3) and a.dtype == np.uint8
    assert np.array_equal(a, b)
    assert not np.array_equal(a, capture(maze, *POSE, camera, rng=8))


def test_camera_without_lens_effects_is_the_render(maze):
    camera = FrontCamera(320, 240, k1=0.0, k2=0.0, noise_std=0.0, supersample=1)
    assert np.array_equal(capture(maze, *POSE, camera), first_person(maze, *POSE, size=(320, 240)))


def test_undistorting_with_the_calibration_recovers_the_pinhole_view(maze):
    camera = FrontCamera(640, 480, k1=-0.15, k2=0.02, noise_std=0.0, supersample=1)
    calib = camera.calibration()
    frame = capture(maze, *POSE, camera).astype(np.float32)
    # The pinhole view of the calibration's intrinsics, drawn directly.
    render_w, render_h = camera._maps[2]
    pinhole = first_person(maze, *POSE, size=(render_w, render_h))
    f_r = (render_w / 2) / np.tan(camera.hfov_rad / 2)
    scale = f_r / calib.fx
    ideal = cv2.warpAffine(
        pinhole,
        np.array(
            [[scale, 0, (render_w - 1) / 2 - scale * calib.cx], [0, scale, (0.42 * render_h - 0.5) - scale * calib.cy]]
        ),
        (640, 480),
        flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
    ).astype(np.float32)
    matrix = np.array([[calib.fx, 0, calib.cx], [0, calib.fy, calib.cy], [0, 0, 1]])
    undistorted = cv2.undistort(frame, matrix, np.array([calib.k1, calib.k2, 0.0, 0.0])).astype(np.float32)
    inner = (slice(60, 420), slice(80, 560))
    raw_err = np.abs(frame[inner] - ideal[inner]).mean()
    fixed_err = np.abs(undistorted[inner] - ideal[inner]).mean()
    assert fixed_err < 2.0 < raw_err


def test_gain_brightens_and_saturates(maze):
    base = capture(maze, *POSE, FrontCamera(320, 240, noise_std=0.0))
    bright = capture(maze, *POSE, FrontCamera(320, 240, gain=4.0, noise_std=0.0))
    assert bright.mean() > 2 * base.mean()
    assert (bright == 255).mean() > 0.3


def test_camera_rejects_wild_settings():
    with pytest.raises(ValueError, match="not mild"):
        FrontCamera(k1=-0.9)
    with pytest.raises(ValueError, match="camera size"):
        FrontCamera(width=8)


def test_calibration_round_trips_through_json(tmp_path):
    colours = {"red": ColourClass((0.1, 0.2, 5.0), ((1, 0, 0), (0, 1, 0), (0, 0, 1)))}
    calib = FrontCamera(320, 240).calibration(colours)
    path = calib.save(tmp_path / "lab" / "front_camera.json")
    loaded = CameraCalibration.load(path)
    assert loaded == calib
    data = json.loads(path.read_text())
    assert set(data) == {
        "version",
        "image_size",
        "intrinsics",
        "distortion",
        "camera_height_m",
        "camera_pitch_rad",
        "colours",
        "object_depth_offset_m",
    }
    assert data["image_size"] == [320, 240]


@pytest.mark.parametrize(
    "mutate, message",
    [
        (lambda d: d.pop("intrinsics"), "missing or malformed"),
        (lambda d: d.update(version=99), "version 99"),
        (
            lambda d: d["colours"].update(purple={"mean": [0, 0, 0], "cov": [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}),
            "unknown colour classes",
        ),
        (lambda d: d["colours"].update(red={"mean": [0, 0], "cov": [[1]]}), "colours.red"),
        (
            lambda d: d["colours"].update(red={"mean": [0, 0, 0], "cov": [[1, 0, 0], [0, -1, 0], [0, 0, 1]]}),
            "positive definite",
        ),
        (lambda d: d.update(camera_height_m=-1), "camera_height_m"),
    ],
)
def test_bad_calibration_files_are_clear_errors(tmp_path, mutate, message):
    data = FrontCamera(320, 240).calibration().to_json()
    mutate(data)
    path = tmp_path / "calib.json"
    path.write_text(json.dumps(data))
    with pytest.raises(CalibrationError, match=message):
        CameraCalibration.load(path)


def test_unreadable_calibration_file(tmp_path):
    with pytest.raises(CalibrationError, match="cannot read"):
        CameraCalibration.load(tmp_path / "absent.json")
    (tmp_path / "bad.json").write_text("{not json")
    with pytest.raises(CalibrationError, match="not JSON"):
        CameraCalibration.load(tmp_path / "bad.json")

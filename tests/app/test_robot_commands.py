"""`robotslang robot create|list`: the token is printed once and accepted by the server's check;
the list never shows it; bad names and roles are refused by name."""

from __future__ import annotations

import pytest
from sqlalchemy import create_engine
from sqlalchemy.orm import Session

from app.rover.records import robot_for_token
from tests.app.live import cli


@pytest.mark.slow
def test_robot_create_prints_a_working_token_once_and_list_shows_the_robots(tmp_path):
    env = {"ROBOTSLANG_DATA_DIR": str(tmp_path / "var"), "ROBOTSLANG_SECRET_KEY": "k"}
    made = cli("robot", "create", "rover 1", env=env)
    assert made.returncode == 0, made.stderr
    token = made.stdout.splitlines()[2]
    assert "robot 'rover 1' (driver) registered" in made.stdout and "backend robot:1" in made.stdout
    assert f"robotslang-robot --server URL --token {token}" in made.stdout
    camera = cli("robot", "create", "table camera", "--role", "overhead", env=env)
    assert camera.returncode == 0 and "--role overhead" in camera.stdout, camera.stderr

    with Session(create_engine(f"sqlite:///{tmp_path / 'var' / 'robotslang.db'}")) as db:
        assert robot_for_token(db, token).name == "rover 1"

    listed = cli("robot", "list", env=env)
    assert listed.returncode == 0, listed.stderr
    rows = [line.split(None, 3) for line in listed.stdout.splitlines()]
    assert rows == [["1", "driver", "robot:1", "rover 1"], ["2", "overhead", "-", "table camera"]]
    assert token not in listed.stdout

    again = cli("robot", "create", "rover 1", env=env)
    assert again.returncode != 0 and "robot 'rover 1' already exists" in again.stderr
    bad = cli("robot", "create", "rover 2", "--role", "pilot", env=env)
    assert bad.returncode != 0 and "--role" in bad.stderr and "robot role 'pilot'" in bad.stderr
    assert cli("robot", "list", env=env).stdout == listed.stdout, "a refused robot is not registered"


def test_calibrate_overhead_stores_the_calibration_the_tracker_uses(tmp_path):
    import cv2
    import numpy as np

    from sim.robot.overhead import render_overhead
    from sim.robot.tracking import OverheadCalibration, OverheadTracker
    from sim.tasks.library import MazeLibrary

    maze = MazeLibrary().load("gen-001")
    picture = tmp_path / "table.png"
    cv2.imwrite(str(picture), render_overhead(maze, None))
    env = {"ROBOTSLANG_DATA_DIR": str(tmp_path / "var")}
    done = cli("robot", "calibrate-overhead", "--image", str(picture), env=env)
    assert done.returncode == 0, done.stderr
    stored = tmp_path / "var" / "overhead_calibration.json"
    assert "calibrated 960x720 frames" in done.stdout and str(stored) in done.stdout
    pose = OverheadTracker(OverheadCalibration.load(stored)).update(render_overhead(maze, (1.5, 0.7, 2.0)), 1)
    assert np.hypot(pose.x - 1.5, pose.y - 0.7) < 0.005

    # A camera is anything OpenCV opens: here a video file; --out and the setting choose the file.
    video = tmp_path / "camera.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 5, (960, 720))
    for _ in range(3):
        writer.write(render_overhead(maze, (1.0, 1.0, 0.0)))
    writer.release()
    out = tmp_path / "lab" / "cal.json"
    assert cli("robot", "calibrate-overhead", "--camera", str(video), "--out", str(out), env=env).returncode == 0
    assert OverheadCalibration.load(out).image_size == (960, 720)
    setting = tmp_path / "set.json"
    by_setting = cli(
        "robot",
        "calibrate-overhead",
        "--image",
        str(picture),
        env={**env, "ROBOTSLANG_OVERHEAD_CALIBRATION": str(setting)},
    )
    assert by_setting.returncode == 0 and setting.exists(), by_setting.stderr


def test_calibrate_overhead_refuses_a_view_without_the_markers_and_keeps_the_old_file(tmp_path):
    import cv2
    import numpy as np

    env = {"ROBOTSLANG_DATA_DIR": str(tmp_path / "var"), "COLUMNS": "400"}  # rich wraps long paths otherwise
    stored = tmp_path / "var" / "overhead_calibration.json"
    stored.parent.mkdir()
    stored.write_text("kept")
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((720, 960, 3), 90, np.uint8))
    refused = cli("robot", "calibrate-overhead", "--image", str(blank), env=env)
    assert refused.returncode == 1 and "corner markers [0, 1, 2, 3] not seen" in refused.stderr
    not_image = cli("robot", "calibrate-overhead", "--image", str(stored), env=env)
    assert not_image.returncode == 2 and "not a readable image" in not_image.stderr
    no_camera = cli("robot", "calibrate-overhead", "--camera", str(tmp_path / "none.avi"), env=env)
    assert no_camera.returncode == 2 and "no frame from this camera" in no_camera.stderr
    neither = cli("robot", "calibrate-overhead", env=env)
    assert neither.returncode == 2 and "exactly one of --camera and --image" in neither.stderr
    assert stored.read_text() == "kept"


@pytest.mark.slow
def test_calibrate_camera_from_frames_at_known_poses_makes_a_camera_perception_reads(tmp_path):
    import json
    import math

    import cv2
    import numpy as np

    from sim.core.navgraph import NavGraph
    from sim.core.observations import cast_rays
    from sim.robot.camera import CameraCalibration, FrontCamera, capture
    from sim.robot.perception import perceive, random_poses
    from sim.tasks.library import MazeLibrary

    maze = MazeLibrary().load("gen-001")
    poses = random_poses(maze, NavGraph.build(maze), 60, np.random.default_rng(3))
    camera = FrontCamera()  # the rover's: lens distortion, noise
    folder = tmp_path / "frames"
    folder.mkdir()
    listing = []
    for i, (x, y, theta) in enumerate(poses[:48]):
        cv2.imwrite(str(folder / f"f{i}.png"), capture(maze, x, y, theta, camera, rng=i))
        listing.append({"image": f"f{i}.png", "x": float(x), "y": float(y), "heading_deg": math.degrees(theta)})
    (folder / "poses.json").write_text(json.dumps(listing))
    env = {"ROBOTSLANG_DATA_DIR": str(tmp_path / "var")}
    done = cli("robot", "calibrate-camera", "--frames", str(folder), "--maze", "gen-001", env=env)
    assert done.returncode == 0, done.stderr
    stored = tmp_path / "var" / "camera_calibration.json"
    assert "camera calibrated" in done.stdout and str(stored) in done.stdout
    calibration = CameraCalibration.load(stored)
    # Frames it never saw: the rays' labels where perception is sure of them.
    right = total = 0
    for i, (x, y, theta) in enumerate(poses[48:]):
        seen = perceive(capture(maze, x, y, theta, camera, rng=100 + i), calibration)
        labels, _ = cast_rays(maze, x, y, theta)
        right += int(np.sum(seen.labels[seen.valid] == labels[seen.valid]))
        total += int(np.sum(seen.valid))
    assert total > 12 * 13 * 0.5 and right / total > 0.9, (right, total)

    (folder / "poses.json").write_text(json.dumps([{"image": "missing.png", "x": 1, "y": 1, "heading_deg": 0}]))
    bad = cli(
        "robot", "calibrate-camera", "--frames", str(folder), "--maze", "gen-001", "--out", str(tmp_path / "x"), env=env
    )
    assert bad.returncode != 0 and "missing.png" in bad.stderr and not (tmp_path / "x").exists()
    both = cli("robot", "calibrate-camera", "--virtual", "--frames", str(folder), env=env)
    assert both.returncode != 0 and "exactly one of --virtual and --frames" in both.stderr

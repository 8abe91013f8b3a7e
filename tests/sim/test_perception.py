"""Perception on camera frames with known truth: rays as the simulator has them, and bad frames."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from sim.core.geometry import HEADINGS, TURN_RAD, heading_index
from sim.core.labels import N_LABELS, OBJECT_LABELS, WALL_LABELS
from sim.core.navgraph import NavGraph
from sim.core.observations import N_RAYS, OBS_FEATURES, RayTable, cast_rays, too_close
from sim.core.rays import FrameProblem, RayObservation
from sim.robot.camera import CameraCalibration, FrontCamera, capture
from sim.robot.perception import (
    PerceptionError,
    evaluate_perception,
    features,
    perceive,
    random_poses,
    simulated_calibration,
)
from sim.tasks.library import MazeLibrary

CAMERA = FrontCamera()  # 640x480, barrel distortion, noise: the virtual rover's default


@pytest.fixture(scope="module")
def lib():
    return MazeLibrary()


@pytest.fixture(scope="module")
def calibration(lib):
    # Calibrated in a "lab" on other mazes than those measured below.
    worlds = [(m, NavGraph.build(m)) for m in (lib.load("gen-010"), lib.load("gen-011"))]
    return simulated_calibration(CAMERA, worlds, n_frames=40, seed=11)


@pytest.fixture(scope="module")
def world(lib):
    maze = lib.load("gen-000")
    return maze, NavGraph.build(maze)


def test_rays_match_the_simulator_at_random_poses(world, calibration):
    maze, graph = world
    rng = np.random.default_rng(3)
    wall_right = wall_total = 0
    depth_err, close_ok = [], 0
    poses = random_poses(maze, graph, 30, rng)
    for x, y, theta in poses:
        heading = heading_index(theta)
        labels, depth = cast_rays(maze, x, y, theta)
        obs = perceive(capture(maze, x, y, theta, CAMERA, rng), calibration, heading)
        wall = np.isin(labels, WALL_LABELS)
        wall_right += int((wall & obs.valid & (obs.labels == labels)).sum())
        wall_total += int(wall.sum())
        near = wall & (depth <= 1.0) & obs.valid
        depth_err.extend(np.abs(obs.depth[near] - depth[near]))
        close_ok += int((obs.too_close == too_close(depth, heading)).sum())
    assert wall_right / wall_total >= 0.95
    assert len(depth_err) > 100 and np.mean(depth_err) <= 0.03
    assert close_ok / (len(poses) * N_RAYS) >= 0.95


@pytest.mark.parametrize("label", OBJECT_LABELS)
def test_a_landmark_in_view_is_read_where_its_footprint_begins(world, calibration, label):
    """Facing a jar, mug or paddle from 20 to 45 cm: the ray at its centre, and (but for a ray
    grazing the footprint's rim) every ray that meets it on the map, read it as that object, at
    the footprint's edge, too close exactly when `RayTable` says so."""
    maze, graph = world
    ox, oy = maze.objects[label.word]
    rng = np.random.default_rng(8)
    right = close_right = rays_seen = poses = 0
    for node in np.nonzero(np.abs(np.hypot(graph.nodes[:, 0] - ox, graph.nodes[:, 1] - oy) - 0.325) < 0.125)[0]:
        x, y = graph.nodes[node]
        theta = float(np.arctan2(oy - y, ox - x))
        labels, depth = cast_rays(maze, x, y, theta)
        if labels[N_RAYS // 2] != label:
            continue  # a wall stands between
        heading = heading_index(theta)
        obs = perceive(capture(maze, x, y, theta, CAMERA, rng), calibration, heading)
        centre = N_RAYS // 2
        assert obs.valid[centre] and obs.labels[centre] == label
        assert abs(obs.depth[centre] - depth[centre]) < 0.01
        rays = labels == label
        read = obs.valid & (obs.labels == label) & (np.abs(obs.depth - depth) < 0.02)
        right += int((read & rays).sum())
        close_right += int((obs.too_close == too_close(depth, heading))[rays].sum())
        rays_seen += int(rays.sum())
        poses += 1
    assert poses >= 5
    assert right >= 0.95 * rays_seen and close_right >= 0.98 * rays_seen


def test_features_have_the_ray_tables_layout(world):
    maze, graph = world
    table = RayTable.build(maze, graph, use_cache=False)
    node, heading = graph.n // 2, 3
    obs = RayObservation(
        table.labels[node, heading],
        table.depth[node, heading],
        table.too_close[node, heading],
        np.ones(N_RAYS, bool),
        bool(table.forward_blocked[node, heading]),
    )
    assert np.array_equal(features(obs), table.features()[node, heading])


def test_perceived_features_agree_with_the_table_at_a_node(world, calibration):
    maze, graph = world
    table = RayTable.build(maze, graph, use_cache=False)
    rng = np.random.default_rng(5)
    agree = 0
    for node in rng.choice(graph.n, 12, replace=False):
        heading = int(rng.integers(HEADINGS))
        x, y = graph.nodes[node]
        f = features(perceive(capture(maze, x, y, heading * TURN_RAD, CAMERA, rng), calibration, heading))
        want = table.features()[node, heading]
        assert f.shape == (OBS_FEATURES,) and f.dtype == np.float32
        onehot = slice(0, N_RAYS * N_LABELS)
        agree += int(
            (f[onehot].reshape(N_RAYS, N_LABELS).argmax(1) == want[onehot].reshape(N_RAYS, N_LABELS).argmax(1)).sum()
        )
    assert agree >= 0.85 * 12 * N_RAYS


def test_jpeg_frames_read_about_as_well_as_raw_ones(world, calibration):
    maze, graph = world
    rng = np.random.default_rng(6)
    right = {"raw": 0, "jpeg": 0}
    for x, y, theta in random_poses(maze, graph, 8, rng):
        labels, _ = cast_rays(maze, x, y, theta)
        frame = capture(maze, x, y, theta, CAMERA, rng)
        ok, jpeg = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, 85])
        for kind, data in (("raw", frame), ("jpeg", jpeg.tobytes())):
            obs = perceive(data, calibration)
            right[kind] += int((obs.valid & (obs.labels == labels)).sum())
    assert right["jpeg"] >= right["raw"] - 4 >= 0.8 * 8 * N_RAYS - 4


@pytest.mark.parametrize("gain, problem", [(0.05, FrameProblem.DARK), (6.0, FrameProblem.OVEREXPOSED)])
def test_unreadable_frames_give_no_rays_not_guesses(world, calibration, gain, problem):
    maze, _ = world
    camera = FrontCamera(gain=gain)
    obs = perceive(capture(maze, 0.6, 0.5, 0.4, camera, 2), calibration)
    assert obs.problem == problem and obs.confidence == 0.0
    f = features(obs)
    assert not f[:-1].any()  # no label, no depth, no too-close


def test_walls_of_a_colour_the_lab_never_saw_are_not_read(world, calibration):
    maze, _ = world
    frame = capture(maze, 0.6, 0.5, 0.4, CAMERA, 3)
    frame[:-40] = (40, 140, 250)  # all but the floor at the rover's feet turns orange
    obs = perceive(frame, calibration)
    assert obs.problem is None and obs.confidence == 0.0


@pytest.mark.parametrize(
    "frame, message",
    [
        (np.zeros((240, 320, 3), np.uint8), "calibration is for 640x480"),
        (np.zeros((480, 640), np.uint8), r"\(H, W, 3\) uint8"),
        (np.zeros((480, 640, 3), np.float32), r"\(H, W, 3\) uint8"),
        (b"not a jpeg at all", "not a JPEG"),
        (b"", "not a JPEG"),
        ("frame.jpg", "got str"),
    ],
)
def test_frames_that_are_not_camera_images_are_clear_errors(calibration, frame, message):
    with pytest.raises(PerceptionError, match=message):
        perceive(frame, calibration)


def test_a_calibration_without_colours_is_refused():
    with pytest.raises(PerceptionError, match="calibrate_colours"):
        perceive(np.zeros((480, 640, 3), np.uint8), CAMERA.calibration())


def test_colour_calibration_survives_its_file(world, calibration, tmp_path):
    maze, _ = world
    loaded = CameraCalibration.load(calibration.save(tmp_path / "front.json"))
    frame = capture(maze, 1.0, 0.8, 2.0, CAMERA, 4)
    a, b = perceive(frame, calibration), perceive(frame, loaded)
    assert np.array_equal(a.labels, b.labels) and np.allclose(a.depth, b.depth)


@pytest.mark.benchmark_data
def test_rays_match_on_the_benchmarks_own_mazes(benchmark_path, calibration):
    lib = MazeLibrary(benchmark=benchmark_path)
    mazes = [lib.load(name) for name in [n for n in lib.names() if n.startswith("Run_")][:3]]
    result = evaluate_perception(mazes, n_poses=24, seed=2, camera=CAMERA, calibration=calibration)
    assert result["label_accuracy"] >= 0.95 and result["walls_label_accuracy"] >= 0.95
    assert result["depth_mae_m"] <= 0.03
    assert result["too_close_accuracy"] >= 0.98 and result["walls_too_close_accuracy"] >= 0.98

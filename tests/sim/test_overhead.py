"""The overhead camera's render: markers where the camera model puts them, deterministic per seed."""

from __future__ import annotations

import numpy as np
import pytest

from sim.robot.fiducials import MarkerLayout, detect, detector, square
from sim.robot.overhead import Imaging, OverheadCamera, render_overhead
from sim.tasks.library import MazeLibrary
from tests.sim.helpers import project

LAYOUT = MarkerLayout()


@pytest.fixture(scope="module")
def maze():
    return MazeLibrary().load("gen-002")


@pytest.mark.parametrize(
    "camera", [OverheadCamera(), OverheadCamera(width=1280, height=720, fov_deg=85, position=(1.1, -0.6, 2.2))]
)
def test_every_marker_is_seen_where_the_camera_model_projects_it(maze, camera):
    pose = (0.7, 1.5, 2.4)
    image = render_overhead(maze, pose, camera=camera, seed=4)
    assert image.shape == (camera.height, camera.width, 3) and image.dtype == np.uint8
    found = detect(detector(), image)
    assert sorted(found) == sorted((*LAYOUT.corner_ids, LAYOUT.rover_id))
    expected = {i: project(camera, np.c_[LAYOUT.corner_points(i), np.zeros(4)]) for i in LAYOUT.corner_ids}
    expected[LAYOUT.rover_id] = project(
        camera, np.c_[square(*pose, LAYOUT.rover_size_m), np.full(4, LAYOUT.rover_height_m)]
    )
    # In ArUco's corner order, so the rover's marker is printed up along its heading; the
    # detector's own sub-pixel error on markers 25-45 px across is what remains.
    errors = np.concatenate([np.linalg.norm(found[i][0] - expected[i], axis=1) for i in expected])
    assert np.median(errors) < 0.6 and errors.max() < 2.0


def test_the_plane_homography_agrees_with_the_projection():
    camera = OverheadCamera()
    points = np.array([[0.3, 0.2], [2.0, 1.7], [1.2, 0.9]])
    for z in (0.0, 0.09):
        h = camera.plane_homography(z)
        uvw = np.c_[points, np.ones(3)] @ h.T
        assert np.allclose(uvw[:, :2] / uvw[:, 2:], project(camera, np.c_[points, np.full(3, z)]))


def test_a_render_is_the_same_for_a_seed_and_its_noise_differs_between_seeds(maze):
    a = render_overhead(maze, (1.0, 1.0, 0.3), seed=7)
    assert np.array_equal(a, render_overhead(maze, (1.0, 1.0, 0.3), seed=7))
    assert not np.array_equal(a, render_overhead(maze, (1.0, 1.0, 0.3), seed=8))
    clean = render_overhead(maze, (1.0, 1.0, 0.3), imaging=Imaging(noise=0))
    assert 1.5 < np.std(a.astype(float) - clean) < 3.5, "the default noise is 2.5 grey levels"


def test_exposure_darkens_or_burns_out_the_picture(maze):
    normal = render_overhead(maze, None).mean()
    assert render_overhead(maze, None, imaging=Imaging(exposure=0.1)).mean() < 0.2 * normal
    burnt = render_overhead(maze, None, imaging=Imaging(exposure=8.0))
    assert (burnt == 255).mean() > 0.8

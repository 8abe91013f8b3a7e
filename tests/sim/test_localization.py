"""The particle filter: odometry with collisions, belief from a uniform start, convergence on
camera frames through perception, and frames that say nothing."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from sim.core.dynamics import Action
from sim.core.geometry import GRID_STEP_M, TURN_RAD, pixel_to_world
from sim.core.labels import Label
from sim.core.navgraph import NavGraph
from sim.core.observations import PX_PER_M_X, WALL_CLEARANCE_M
from sim.robot.camera import FrontCamera, capture
from sim.robot.localization import FreeSpace, MotionNoise, ParticleFilter, apply_move, evaluate_filter, free_space
from sim.robot.perception import perceive, simulated_calibration
from sim.tasks.library import MazeLibrary

CAMERA = FrontCamera()
NO_NOISE = MotionNoise(0.0, 0.0, 0.0)


@pytest.fixture(scope="module")
def maze():
    return MazeLibrary().load("gen-001")


@pytest.fixture(scope="module")
def calibration(maze):
    lib = MazeLibrary()
    worlds = [(m, NavGraph.build(m)) for m in (lib.load("gen-010"), lib.load("gen-011"))]
    return simulated_calibration(CAMERA, worlds, n_frames=40, seed=12)


def test_moves_advance_turn_and_stop_at_walls(maze):
    space = free_space(maze)
    rng = np.random.default_rng(0)
    start = space.sample(1, rng)
    ahead, collided = apply_move(start, Action.FORWARD, rng, space, NO_NOISE)
    if not collided[0]:
        assert np.hypot(*(ahead[0, :2] - start[0, :2])) == pytest.approx(GRID_STEP_M)
    turned, _ = apply_move(start, Action.LEFT, rng, space, NO_NOISE)
    assert np.cos(turned[0, 2] - start[0, 2] - TURN_RAD) == pytest.approx(1.0)
    # Driving on in one direction ends at a wall, where the rover stays.
    pose, hits = start, []
    for _ in range(60):
        pose_next, collided = apply_move(pose, Action.FORWARD, rng, space, NO_NOISE)
        hits.append(bool(collided[0]))
        if collided[0]:
            assert np.array_equal(pose_next[0, :2], pose[0, :2])
        pose = pose_next
    assert any(hits) and space.contains(pose[:, 0], pose[:, 1])[0]


def test_the_belief_starts_uniform_and_compact_for_display(maze):
    pf = ParticleFilter(maze, n_particles=1000, seed=1)
    b = pf.belief()
    assert b.spread_m > 0.4
    assert 50 <= len(b.cloud) <= 200 and b.cloud.shape[1] == 4
    assert b.cloud[:, 3].sum() == pytest.approx(1.0)
    assert free_space(maze).contains(pf.particles[:, 0], pf.particles[:, 1]).all()


def test_the_free_space_says_of_every_pixel_what_the_clearance_grid_says(maze):
    # Kept as runs of free cells, not a grid; asked pixel by pixel it must be that grid.
    dist_px = cv2.distanceTransform((maze.walls == Label.FLOOR).astype(np.uint8), cv2.DIST_L2, 5)
    grid = dist_px >= WALL_CLEARANCE_M * PX_PER_M_X
    rows, cols = np.indices(grid.shape)
    x, y = pixel_to_world(cols.ravel(), rows.ravel())
    space = FreeSpace(maze)
    assert np.array_equal(space.contains(x, y), grid.ravel())
    assert space.n_cells == grid.sum()
    assert not space.contains(np.array([-0.01, 0.5, 9.0]), np.array([0.5, -0.01, 0.5])).any()  # off the table


def test_a_filter_holds_little_beyond_its_maze_and_particles(maze):
    # A server keeps a filter per live trial (each on its own maze in a study): its maps must
    # not cost several maze grids each, as the float clearance and the bool free grid did.
    pf = ParticleFilter(maze, n_particles=1500, seed=3)
    maps = pf.caster.clearance.nbytes + sum(a.nbytes for a in vars(pf.space).values() if isinstance(a, np.ndarray))
    assert maps < 0.25 * maze.labels.nbytes  # 1.6 MB: what one bool grid of the maze would cost
    assert pf.caster.labels is maze.labels or np.shares_memory(pf.caster.labels, maze.labels)


def test_an_unreadable_frame_leaves_the_belief_alone(maze, calibration):
    pf = ParticleFilter(maze, n_particles=500, seed=2)
    before = pf.particles.copy(), pf.log_w.copy()
    dark = capture(maze, 1.0, 1.0, 0.0, FrontCamera(gain=0.05), 0)
    pf.update(perceive(dark, calibration))
    assert np.array_equal(pf.particles, before[0]) and np.array_equal(pf.log_w, before[1])


def test_the_filter_finds_the_rover_from_a_uniform_start(maze, calibration):
    result = evaluate_filter(maze, episodes=5, moves=20, seed=4, n_particles=1000, calibration=calibration)
    assert result["converged_fraction_20_moves"] >= 0.8
    assert len(result["curve"]) == 21
    assert result["curve"][-1] < result["curve"][0]

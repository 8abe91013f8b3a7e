"""The software rover's physics on mazes whose walls are known exactly."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.core.geometry import GRID_STEP_M, TURN_RAD, pixel_to_world, world_to_pixel
from sim.core.maze import Maze
from sim.robot.rover import BODY_RADIUS_M, NOISE_MODELS, MotionNoise, Move, Rover, RoverPose
from tests.sim.helpers import open_table, wall_at_x

WALL_X = 1.5  # a blue wall 10 px thick, the full height of the table
WALL_FACE_X = float(pixel_to_world(int(world_to_pixel(WALL_X, 0)[0]) - 5, 0)[0])  # its left face


@pytest.fixture(scope="module")
def maze() -> Maze:
    return Maze.from_labels(wall_at_x(open_table(), WALL_X), "walled")


def exact(maze, x=0.6, y=1.0, theta=0.0) -> Rover:
    return Rover(maze, RoverPose(x, y, theta), NOISE_MODELS["none"])


def test_without_noise_a_step_is_0_07_m_along_the_heading_and_a_turn_45_degrees(maze):
    rover = exact(maze, theta=math.radians(30))
    result = rover.move(Move.FORWARD)
    assert not result.collided
    assert (result.pose.x, result.pose.y) == pytest.approx(
        (0.6 + GRID_STEP_M * math.cos(math.radians(30)), 1.0 + GRID_STEP_M * math.sin(math.radians(30))), abs=1e-9
    )
    assert rover.move("left").pose.theta == pytest.approx(math.radians(75))
    for _ in range(3):
        rover.move("right")
    assert rover.pose.theta == pytest.approx(math.radians(30) - 2 * TURN_RAD + 2 * math.pi)
    assert (rover.pose.x, rover.pose.y) == pytest.approx((result.pose.x, result.pose.y), abs=1e-12)


def test_the_same_seed_gives_the_same_poses_and_another_seed_others(maze):
    def run(seed):
        rover = Rover(maze, RoverPose(0.6, 1.0, 0.0), NOISE_MODELS["default"], seed=seed)
        return [rover.move(m).pose for m in ["forward", "left", "forward", "right", "forward"]]

    assert run(7) == run(7)
    assert run(7) != run(8)


def test_default_noise_is_a_few_millimetres_per_step_and_a_degree_or_two_per_turn(maze):
    rover = Rover(maze, RoverPose(0.6, 1.0, 0.0), NOISE_MODELS["default"], seed=1)
    steps = [rover.plan("forward").path[-1] for _ in range(2000)]
    lengths = np.array([math.hypot(x - 0.6, y - 1.0) for x, y, _ in steps])
    bends = np.degrees([theta for _, _, theta in steps])
    turns = np.degrees([rover.plan("left").path[-1][2] for _ in range(2000)])
    assert abs(lengths.mean() - GRID_STEP_M) < 0.0005 and 0.001 < lengths.std() < 0.004
    assert np.mean(np.abs(lengths - GRID_STEP_M) < 0.005) > 0.95
    assert abs(bends.mean()) < 0.1 and 0.2 < bends.std() < 1.0
    assert abs(turns.mean() - 45) < 0.1 and np.mean(np.abs(turns - 45) <= 2.0) > 0.9
    assert rover.pose == RoverPose(0.6, 1.0, 0.0)  # planning alone moves nothing


def test_a_wall_stops_the_rover_where_its_body_touches_and_it_stays_stopped(maze):
    rover = exact(maze, x=1.2, y=1.4)
    results = [rover.move("forward") for _ in range(8)]
    free = [not r.collided for r in results]
    assert free[:3] == [True] * 3 and not any(free[5:])  # 1.2 + 3 steps is clear; 5 steps is not
    stop = results[-1].pose
    assert stop.x == pytest.approx(WALL_FACE_X - BODY_RADIUS_M, abs=0.003)
    assert rover.clearance_m(stop.x, stop.y) >= BODY_RADIUS_M
    assert all(r.pose == stop for r in results[5:])
    # Turned around, it drives away freely.
    rover.move("left"), rover.move("left"), rover.move("left"), rover.move("left")
    away = rover.move("forward")
    assert not away.collided and away.pose.x == pytest.approx(stop.x - GRID_STEP_M)


def test_objects_and_the_table_edge_stop_the_rover_too(maze):
    jar_x, jar_y = maze.objects["jar"]  # a 16 px square at (0.5, 0.5)
    rover = exact(maze, x=jar_x - 0.3, y=jar_y)
    for _ in range(6):
        last = rover.move("forward")
    assert last.collided and rover.pose.x < jar_x - BODY_RADIUS_M
    edge = exact(maze, x=0.2, y=1.0, theta=math.pi)
    for _ in range(5):
        last = edge.move("forward")
    assert last.collided and BODY_RADIUS_M <= edge.pose.x < 0.1


def test_a_pulse_cut_short_leaves_the_rover_part_way(maze):
    rover = exact(maze)
    pulse = rover.plan("forward")
    result = rover.finish(pulse, 0.5)
    assert result.pose.x == pytest.approx(0.6 + GRID_STEP_M / 2) and not result.collided
    turn = rover.finish(rover.plan("left"), 0.25)
    assert turn.pose.theta == pytest.approx(TURN_RAD / 4)


def test_a_start_inside_a_wall_or_off_the_table_is_refused(maze):
    with pytest.raises(ValueError, match="within 0.067 m .* of a wall"):
        exact(maze, x=WALL_X)
    with pytest.raises(ValueError, match="off the 2.4638 x 2.0574 m table"):
        exact(maze, x=-0.1)
    with pytest.raises(ValueError, match="unknown noise model 'wild'"):
        MotionNoise.named("wild")

"""Playing a trial as its two seats, with the shortest path choosing the Driver's moves."""

from __future__ import annotations

import itertools
import math

import cv2
import numpy as np

from sim.core.dynamics import Action, snap_pose, teacher_action
from sim.core.geometry import heading_index
from sim.core.labels import LABEL_BGR, Label

_ids = itertools.count()


def oracle_action(services, trial_id: int) -> Action:
    """The shortest-path move toward the current target, from the simulator's true pose."""
    runtime = services.hub.peek(trial_id)
    state = runtime.state
    graph, maze = services.mazes.graph(state.maze), services.mazes.load(state.maze)
    goal = graph.nearest_node(*maze.objects[state.current_target])
    return teacher_action(graph, snap_pose(graph, *runtime.robot.backend.pose()), goal)


def facing_action(services, trial_id: int) -> Action:
    """The turn toward the current target's object from where the robot stands (STOP once it
    faces it): a Driver looks at the target before claiming it."""
    runtime = services.hub.peek(trial_id)
    state = runtime.state
    graph, maze = services.mazes.graph(state.maze), services.mazes.load(state.maze)
    pose = snap_pose(graph, *runtime.robot.backend.pose())
    (x, y), (ox, oy) = graph.nodes[pose.node], maze.objects[state.current_target]
    turn = (heading_index(math.atan2(oy - y, ox - x)) - pose.heading) % 8
    return Action.STOP if turn == 0 else Action.LEFT if turn <= 4 else Action.RIGHT


async def move(driver, action: str) -> dict:
    """The move's outcome (`SeatClient.moved`: ok, collision or refused, and why)."""
    move_id = f"m{next(_ids)}"
    await driver.send("move", action=action, move_id=move_id)
    return await driver.moved(move_id)


async def drive_to_target(services, trial_id: int, driver, max_moves: int = 400) -> int:
    for n in range(max_moves):
        action = oracle_action(services, trial_id)
        if action == Action.STOP:
            return n
        executed = await move(driver, action.word)
        assert executed["outcome"] == "ok", executed
    raise AssertionError(f"target not reached in {max_moves} moves")


async def start_trial(commander, driver) -> None:
    await commander.event("phase", phase="localizing")
    await driver.event("phase", phase="localizing")


async def claim_and_decide(commander, driver, confirm: bool) -> dict:
    start_c, start_d = len(commander.received), len(driver.received)
    await driver.send("claim")
    claimed = await commander.event("target_claimed", start=start_c)
    await commander.send("confirm" if confirm else "reject")
    kind = "target_confirmed" if confirm else "target_rejected"
    await driver.event(kind, start=start_d)
    return claimed


def object_pixels(jpeg: bytes, label: Label) -> int:
    """Pixels whose colour points the way of the object's colour (JPEG blurs it a little)."""
    image = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR).astype(np.float64)
    norm = np.linalg.norm(image, axis=-1)
    ref = np.array(LABEL_BGR[label], dtype=np.float64)
    with np.errstate(invalid="ignore"):
        off = np.linalg.norm(image / norm[..., None] - ref / np.linalg.norm(ref), axis=-1)
    return int(((norm > 60) & (off < 0.12)).sum())

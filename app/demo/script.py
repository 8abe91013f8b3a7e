"""What the scripted players say and do: routes in words from the shortest path and the walls.

Pure functions of the maze, its navigation graph and a pose, so that the words can be checked
without a server. The Commander plans each leg with the teacher (the shortest path) and turns
it into instructions such as "turn left at the red wall" and "go forward until you see the
mug"; the Driver describes what is around it from the map's rays, as a person would from the
camera.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.core.dynamics import Action, Pose, continuous_pose, teacher_action
from sim.core.geometry import GRID_STEP_M, heading_angle, wrap_angle
from sim.core.labels import Label
from sim.core.maze import Maze
from sim.core.navgraph import NavGraph
from sim.core.observations import N_RAYS, RAY_OFFSETS, ray_caster, too_close
from sim.core.rays import RayObservation
from sim.language import vocab
from sim.language.describe import describe
from sim.language.phrases import PhraseKind, Phrases, Phrasing

NEAR_WALL_M = 0.35  # a wall this close ahead is "reached"
OBJECT_WORDS = {label.word: name for label, name in vocab.OBJECT_WORDS.items()}
PHRASES = Phrases(Phrasing.SCRIPTED)  # one template per kind: the scripted Commander's words
MAX_LEG_ACTIONS = 400
CORNER_TOLERANCE_M = 0.1


def what_is_at(maze: Maze, x: float, y: float, angle: float) -> tuple[Label, float]:
    """The first wall or object seen from (x, y) along `angle`, and how far away it is."""
    labels, depth = ray_caster(maze).cast(x, y, angle)
    return Label(int(labels)), float(depth)


def leg_actions(graph: NavGraph, start: Pose, goal_node: int) -> tuple[list[Action], list[Pose]]:
    """The teacher's moves from `start` to the goal node, and the pose after each."""
    actions: list[Action] = []
    poses: list[Pose] = []
    pose = start
    for _ in range(MAX_LEG_ACTIONS):
        action = teacher_action(graph, pose, goal_node)
        if action == Action.STOP:
            break
        pose, _ = graph.moves.step(pose, action)
        actions.append(action)
        poses.append(pose)
    return actions, poses


def corners(points: np.ndarray, tolerance_m: float = CORNER_TOLERANCE_M) -> list[int]:
    """Indices of the path's corners (Douglas-Peucker): the grid's 45 degree zig-zags are not
    turns a person would name."""
    keep = {0, len(points) - 1}
    stack = [(0, len(points) - 1)]
    while stack:
        a, b = stack.pop()
        if b - a < 2:
            continue
        chord = points[b] - points[a]
        rel = points[a + 1 : b] - points[a]
        norm = np.hypot(*chord)
        off = np.abs(chord[0] * rel[:, 1] - chord[1] * rel[:, 0]) / norm if norm else np.hypot(rel[:, 0], rel[:, 1])
        k = int(np.argmax(off))
        if off[k] > tolerance_m:
            keep.add(a + 1 + k)
            stack += [(a, a + 1 + k), (a + 1 + k, b)]
    return sorted(keep)


def _turn_phrase(turn: float) -> str | None:
    """A turn in radians (counter-clockwise positive) in words, None when it is no turn."""
    return PHRASES.turn(int(round(turn / (math.pi / 4))))


@dataclass(frozen=True)
class Leg:
    end: Pose
    actions: tuple[Action, ...]
    instructions: tuple[str, ...]


def plan_leg(maze: Maze, graph: NavGraph, start: Pose, target: str) -> Leg:
    """The shortest way from `start` to `target`, as moves and as the Commander's words."""
    goal = graph.nearest_node(*maze.objects[target])
    actions, poses = leg_actions(graph, start, goal)
    thing = OBJECT_WORDS[target]
    nodes = [start.node] + [p.node for p in poses]
    nodes = [n for i, n in enumerate(nodes) if i == 0 or n != nodes[i - 1]]
    if len(nodes) < 2:
        there = PHRASES.say(PhraseKind.THERE, thing=thing)
        return Leg(poses[-1] if poses else start, tuple(actions), (there,))
    points = graph.nodes[nodes]
    idx = corners(points)
    words = []
    heading = float(heading_angle(start.heading))
    for n, (a, b) in enumerate(zip(idx, idx[1:])):
        direction = math.atan2(*(points[b] - points[a])[::-1])
        turn = _turn_phrase(wrap_angle(direction - heading))
        if n == 0 and turn:
            words.append(turn)
        length = float(np.hypot(*(points[b] - points[a])))
        steps = max(1, int(round(length / GRID_STEP_M)))
        if b == idx[-1]:
            words.append(PHRASES.say(PhraseKind.UNTIL_TARGET, thing=thing))
            break
        after = math.atan2(*(points[idx[n + 2]] - points[b])[::-1])
        next_turn = _turn_phrase(wrap_angle(after - direction)) or "keep going"
        x, y = points[b]
        label, depth = what_is_at(maze, x, y, direction)
        if label != Label.FLOOR and depth < 2 * NEAR_WALL_M:
            words.append(PHRASES.say(PhraseKind.TURN_AT_WALL, turn=next_turn, wall=vocab.wall_name(label)))
        else:
            words.append(PHRASES.say(PhraseKind.FORWARD_THEN_TURN, n=steps, turn=next_turn))
        heading = direction
    return Leg(poses[-1], tuple(actions), tuple(words))


def describe_view(maze: Maze, graph: NavGraph, pose: Pose) -> str:
    """The scripted Driver's answer to "what do you see?": the map's rays ahead, left and right, in
    the words the dialog Driver uses for its frames (`sim.language.describe`)."""
    x, y, theta = continuous_pose(graph, pose)
    views = {}
    for side in (vocab.Side.AHEAD, vocab.Side.LEFT, vocab.Side.RIGHT):
        labels, depth = ray_caster(maze).cast(x, y, theta + vocab.SIDE_STEPS[side] * math.pi / 4 + RAY_OFFSETS)
        heading = (pose.heading + vocab.SIDE_STEPS[side]) % 8
        views[side] = RayObservation(
            labels=labels.astype(np.uint8),
            depth=depth.astype(np.float32),
            too_close=too_close(depth, heading),
            valid=np.ones(N_RAYS, dtype=bool),
            forward_blocked=False,
        )
    return describe(views)

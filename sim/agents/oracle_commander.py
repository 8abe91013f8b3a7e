"""A Commander that cheats: it is handed the Driver's true pose and the map, for measuring Drivers.

It plans each instruction with the shortest path (the teacher) from the true pose, speaks one
instruction at a time in the scripted or the held-out phrasing, and waits for the Driver's answer;
when the Driver strays it plans again from where the Driver truly is. It picks "at the red wall" or
"until you see the mug" only where the map says a Driver stopping at the first close wall (or the
object in reach) would stop where the path turns; elsewhere it counts the steps. It confirms a claim
within 2 robot lengths of the target (the trial judge's rule) and rejects it otherwise. Never ranks
with agents: it sees what no Commander sees."""

from __future__ import annotations

import math

import numpy as np

from sim.agents.turns import (
    Claimed,
    DoJudge,
    DoSay,
    Heard,
    Percept,
    Phase,
    PhaseChanged,
    SeatInfo,
    Speaker,
    Turn,
)
from sim.dynamics import Action, Pose, step, teacher_action
from sim.geometry import SUCCESS_RADIUS_M
from sim.labels import Label, object_label
from sim.language.describe import ahead, at_wall, near, seen
from sim.language.phrases import Kind, Phrases, Phrasing
from sim.language.vocab import OBJECT_WORDS, wall_name
from sim.navgraph import NavGraph
from sim.observations import RayTable
from sim.perception import RayObservation

THERE_M = 0.35  # the Commander says "you are there" this close to the target
MAX_PLAN = 400


class OracleCommander:
    """The Commander's seat agent for benches; `pose` is set by the harness before each percept."""

    def __init__(
        self,
        graph: NavGraph,
        rays: RayTable,
        targets: list[tuple[str, tuple[float, float]]],
        phrasing: Phrasing = Phrasing.SCRIPTED,
        seed: int = 0,
    ) -> None:
        self.graph, self.rays, self.targets = graph, rays, targets
        self.phrases = Phrases(Phrasing(phrasing), seed)
        self.pose = Pose(0, 0)
        self._index: int | None = None

    def reset(self, info: SeatInfo) -> None:
        self._index = None

    def view(self, pose: Pose) -> RayObservation:
        n, h = pose.node, pose.heading
        return RayObservation(
            labels=self.rays.labels[n, h],
            depth=self.rays.depth[n, h],
            too_close=self.rays.too_close[n, h],
            valid=np.ones(self.rays.labels.shape[-1], dtype=bool),
            forward_blocked=bool(self.rays.forward_blocked[n, h]),
        )

    def _target(self) -> tuple[str, Label, tuple[float, float], int]:
        assert self._index is not None  # only while navigating
        name, xy = self.targets[self._index]
        return name, object_label(name), xy, self.graph.nearest_node(*xy)

    def distance(self, pose: Pose) -> float:
        _, _, xy, _ = self._target()
        return float(math.dist(self.graph.nodes[pose.node], xy))

    def perceive(self, percept: Percept) -> list[Turn]:
        if isinstance(percept, PhaseChanged):
            if percept.phase == Phase.LOCALIZING:
                return [DoSay(self.phrases.say(Kind.ASK_VIEW))]
            if percept.phase == Phase.NAVIGATING and percept.target_index is not None:
                self._index = percept.target_index
                name = self._target()[0]
                return [
                    DoSay(
                        f"{self.phrases.say(Kind.ANNOUNCE, thing=OBJECT_WORDS[object_label(name)])}. "
                        f"{self.instruction(plain=False)}"
                    )
                ]
            return []
        if isinstance(percept, Claimed):
            return [DoJudge(self.distance(self.pose) <= SUCCESS_RADIUS_M)]
        if isinstance(percept, Heard) and percept.speaker == Speaker.DRIVER and self._index is not None:
            if "found" in percept.text:
                return []  # a claim is on its way
            return [DoSay(self.instruction(plain="?" in percept.text))]
        return []

    def instruction(self, plain: bool) -> str:
        """The next instruction from the true pose; `plain` (the Driver asked) counts steps."""
        name, label, _, goal = self._target()
        thing = OBJECT_WORDS[label]
        if self.distance(self.pose) <= THERE_M:
            return self.phrases.say(Kind.THERE, thing=thing)
        actions: list[Action] = []
        pose = self.pose
        poses = [pose]
        for _ in range(MAX_PLAN):
            action = teacher_action(self.graph, pose, goal)
            if action == Action.STOP:
                break
            pose, _ = step(self.graph, pose, action)
            actions.append(action)
            poses.append(pose)
        k = 0
        eighths = 0
        while k < len(actions) and actions[k] != Action.FORWARD:
            eighths += 1 if actions[k] == Action.LEFT else -1
            k += 1
        turn = self.phrases.turn(eighths)
        start = k
        while k < len(actions) and actions[k] == Action.FORWARD:
            k += 1
        run = k - start
        if run == 0:
            return turn or self.phrases.say(Kind.THERE, thing=thing)
        words = [turn] if turn else []
        if k == len(actions) and not plain and self._walk_ends(poses[start], label) == run:
            return ", ".join([*words, self.phrases.say(Kind.UNTIL_TARGET, thing=thing)])
        after = 0
        while k < len(actions) and actions[k] != Action.FORWARD:
            after += 1 if actions[k] == Action.LEFT else -1
            k += 1
        next_turn = self.phrases.turn(after)
        wall = self._walk_ends(poses[start], None)
        front = seen(self.view(poses[start + run]))
        if next_turn and not plain and wall == run and front:
            ahead = self._ahead_label(poses[start + run])
            if ahead is not None and any(s.label == ahead for s in seen(self.view(poses[start]))):
                return ", then ".join(
                    [*words, self.phrases.say(Kind.TURN_AT_WALL, turn=next_turn, wall=wall_name(ahead))]
                )
        if next_turn:
            return ", then ".join([*words, self.phrases.say(Kind.FORWARD_THEN_TURN, n=run, turn=next_turn)])
        return ", then ".join([*words, self.phrases.say(Kind.FORWARD, n=run)])

    def _ahead_label(self, pose: Pose) -> Label | None:
        front = ahead(self.view(pose))
        return front.label if front is not None else None

    def _walk_ends(self, pose: Pose, target: Label | None) -> int | None:
        """How many forward moves a Driver walking "until the wall" (or the target) makes from `pose`."""
        for moves in range(MAX_PLAN):
            obs = self.view(pose)
            if (near(obs, target) or obs.forward_blocked) if target is not None else at_wall(obs):
                return moves
            pose, collided = step(self.graph, pose, Action.FORWARD)
            if collided:
                return None
        return None

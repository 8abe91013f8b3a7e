"""A Commander that cheats: it is handed the Driver's true pose and the map, for measuring Drivers.

It plans each instruction with the fewest moves from the true pose, speaks one
instruction at a time in the scripted or the held-out phrasing, and waits for the Driver's answer;
when the Driver strays it plans again from where the Driver truly is. It picks "at the red wall" or
"until you see the mug" only where the map says a Driver stopping at the first close wall (or the
object in reach) would stop where the path turns; elsewhere it counts the steps. It confirms a claim
within 2 robot lengths of the target (the trial judge's rule) and rejects it otherwise. Never ranks
with agents: it sees what no Commander sees."""

from __future__ import annotations

import math

import numpy as np

from sim.agents.sight import pose_rays
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
from sim.dynamics import Action, Pose, step
from sim.geometry import HEADINGS, SUCCESS_RADIUS_M
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
        self._costs: dict[int, np.ndarray] = {}

    def reset(self, info: SeatInfo) -> None:
        self._index = None

    def view(self, pose: Pose) -> RayObservation:
        return pose_rays(self.rays, pose)

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
            if self.distance(self.pose) <= SUCCESS_RADIUS_M:
                return [DoJudge(True)]
            return [DoJudge(False), DoSay(self.phrases.say(Kind.REJECT))]
        if isinstance(percept, Heard) and percept.speaker == Speaker.DRIVER and self._index is not None:
            if "found" in percept.text:
                return []  # a claim is on its way
            return [DoSay(self.instruction(plain="?" in percept.text))]
        return []

    def instruction(self, plain: bool) -> str:
        """The next instruction from the true pose; `plain` (the Driver asked) counts steps."""
        _, label, _, goal = self._target()
        thing = OBJECT_WORDS[label]
        if self.distance(self.pose) <= THERE_M:
            return self.phrases.say(Kind.THERE, thing=thing)
        actions, poses = self.plan(self.pose, goal)
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
        if next_turn and not plain and wall == run:
            ahead = self._ahead_label(poses[start + run])
            if ahead is not None and any(s.label == ahead for s in seen(self.view(poses[start]))):
                return ", then ".join(
                    [*words, self.phrases.say(Kind.TURN_AT_WALL, turn=next_turn, wall=wall_name(ahead))]
                )
        if next_turn:
            return ", then ".join([*words, self.phrases.say(Kind.FORWARD_THEN_TURN, n=run, turn=next_turn)])
        return ", then ".join([*words, self.phrases.say(Kind.FORWARD, n=run)])

    def plan(self, start: Pose, goal: int) -> tuple[list[Action], list[Pose]]:
        """Fewest moves (turns count) to the goal node, forward first among equals: straight runs
        a Commander can name, where the teacher's next-hop path zig-zags at a turn per step."""
        cost = self.moves_to_go(goal)
        pose, actions, poses = start, [], [start]
        while cost[pose.node, pose.heading] > 0:
            for action in (Action.FORWARD, Action.LEFT, Action.RIGHT):
                after, collided = step(self.graph, pose, action)
                if not collided and cost[after.node, after.heading] == cost[pose.node, pose.heading] - 1:
                    break
            else:
                break  # the goal is out of reach from here
            pose = after
            actions.append(action)
            poses.append(pose)
        return actions, poses

    def moves_to_go(self, goal: int) -> np.ndarray:
        """(N, 8) moves from each pose to the goal node, by a breadth-first search backwards."""
        if goal in self._costs:
            return self._costs[goal]
        n = self.graph.n
        cost = np.full((n, HEADINGS), -1, dtype=np.int64)
        cost[goal] = 0
        frontier = [(goal, h) for h in range(HEADINGS)]
        came_from = [[np.flatnonzero(self.graph.forward[:, h] == m) for h in range(HEADINGS)] for m in range(n)]
        while frontier:
            nxt = []
            for node, h in frontier:
                c = cost[node, h] + 1
                before = [(node, (h - 1) % HEADINGS), (node, (h + 1) % HEADINGS)]
                before += [(int(m), h) for m in came_from[node][h]]
                for m, hh in before:
                    if cost[m, hh] < 0:
                        cost[m, hh] = c
                        nxt.append((m, hh))
            frontier = nxt
        cost[cost < 0] = np.iinfo(np.int64).max // 2  # unreachable
        self._costs[goal] = cost
        return cost

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

"""A Commander's next instruction from a pose on the map: the fewest-moves route to the target,
cut at its first straight run and said in the Commander's phrasing.

Both Commanders use it: the oracle from the true pose, the dialog Commander from its estimate.
It reads the map only (graph and the views each pose has), never the Driver's camera."""

from __future__ import annotations

import itertools

import numpy as np

from sim.core.dynamics import Action, Pose
from sim.core.geometry import HEADINGS
from sim.core.labels import WALL_LABELS, Label
from sim.core.navgraph import NavGraph
from sim.core.observations import RayTable
from sim.core.rays import RayObservation
from sim.language.describe import ahead, at_wall, near, seen
from sim.language.phrases import PhraseKind, Phrases
from sim.language.vocab import OBJECT_WORDS, wall_name

MAX_PLAN = 400


class Router:
    """Plans on one maze's graph; the moves-to-go table of each goal is computed once."""

    def __init__(self, graph: NavGraph, rays: RayTable, phrases: Phrases) -> None:
        self.graph, self.rays, self.phrases = graph, rays, phrases
        self._costs: dict[int, np.ndarray] = {}

    def view(self, pose: Pose) -> RayObservation:
        """What the map says a Driver at `pose` sees."""
        return self.rays.observation(*pose)

    def instruction(self, pose: Pose, label: Label, goal: int, plain: bool) -> str:
        """The next instruction from `pose` towards the object `label` at node `goal`; `plain` (the
        Driver asked) counts steps. It picks "at the red wall" or "until you see the mug" only where
        a Driver stopping at the first close wall (or the object in reach) would stop where the path
        turns; elsewhere it counts the steps. (Legs of several such pieces, tried for a person's
        sake, the trained Driver reader reads with clauses dropped: self-play doubled its moves.)"""
        thing = OBJECT_WORDS[label]
        actions, poses = self.plan(pose, goal)
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
            return turn or self.phrases.say(PhraseKind.THERE, thing=thing)
        words = [turn] if turn else []
        if k == len(actions) and not plain and self._walk_ends(poses[start], label) == run:
            return ", ".join([*words, self.phrases.say(PhraseKind.UNTIL_TARGET, thing=thing)])
        after = 0
        while k < len(actions) and actions[k] != Action.FORWARD:
            after += 1 if actions[k] == Action.LEFT else -1
            k += 1
        next_turn = self.phrases.turn(after)
        if next_turn and not plain and (front := self._wall_at_end(poses[start], poses[start + run], run)) is not None:
            return ", then ".join(
                [*words, self.phrases.say(PhraseKind.TURN_AT_WALL, turn=next_turn, wall=wall_name(front))]
            )
        if next_turn:
            return ", then ".join([*words, self.phrases.say(PhraseKind.FORWARD_THEN_TURN, n=run, turn=next_turn)])
        return ", then ".join([*words, self.phrases.say(PhraseKind.FORWARD, n=run)])

    def one_move(self, pose: Pose, label: Label, goal: int) -> str:
        """The route's first move alone, in the simplest words (for a Driver that could not carry
        out the last instructions): a turn, or a walk up to a wall named by its colour (a landmark,
        not a count) where the walk ends at one, else the count."""
        thing = OBJECT_WORDS[label]
        actions, poses = self.plan(pose, goal)
        if actions and actions[0] != Action.FORWARD:
            turned = sum(
                1 if a == Action.LEFT else -1 for a in itertools.takewhile(lambda a: a != Action.FORWARD, actions)
            )
            return self.phrases.turn(turned) or self.phrases.say(PhraseKind.THERE, thing=thing)
        run = sum(1 for _ in itertools.takewhile(lambda a: a == Action.FORWARD, actions))
        if run == 0:
            return self.phrases.say(PhraseKind.THERE, thing=thing)
        if run == len(actions) and self._walk_ends(pose, label) == run:
            return self.phrases.say(PhraseKind.UNTIL_TARGET, thing=thing)
        front = self._wall_at_end(pose, poses[run], run)
        if front is not None:
            return self.phrases.say(PhraseKind.UNTIL_WALL, wall=wall_name(front))
        return self.phrases.say(PhraseKind.FORWARD, n=run)

    def _wall_at_end(self, start: Pose, end: Pose, run: int) -> Label | None:
        """The wall a Driver walking "until the wall" from `start` stops at, facing it at `end`,
        where that walk is the `run` moves of the route and the wall is seen from `start`. Only a
        wall is named: a landmark ahead (it blocks the robot) named there reads as the thing to
        find ("... at the ping-pong paddle": the Driver claims it)."""
        if self._walk_ends(start, None) != run:
            return None
        front = self._ahead_label(end)
        if front in WALL_LABELS and any(s.label == front for s in seen(self.view(start))):
            return front
        return None

    def plan(self, start: Pose, goal: int) -> tuple[list[Action], list[Pose]]:
        """Fewest moves (turns count) to the goal node, forward first among equals: straight runs
        a Commander can name, where the teacher's next-hop path zig-zags at a turn per step."""
        cost = self.moves_to_go(goal)
        pose, actions, poses = start, [], [start]
        while cost[pose.node, pose.heading] > 0:
            for action in (Action.FORWARD, Action.LEFT, Action.RIGHT):
                after, collided = self.graph.moves.step(pose, action)
                if not collided and cost[after.node, after.heading] == cost[pose.node, pose.heading] - 1:
                    break
            else:
                break  # the goal is out of reach from here
            pose = after
            actions.append(action)
            poses.append(pose)
        return actions, poses

    def moves_to_go(self, goal: int) -> np.ndarray:
        """(N, 8) moves from each pose to the goal node, by a breadth-first search backwards over
        where each move leads (`NavGraph.moves`: a collision leads nowhere new)."""
        if goal in self._costs:
            return self._costs[goal]
        after = self.graph.moves.after()
        cost = np.full(len(after), -1, dtype=np.int64)
        cost[goal * HEADINGS : (goal + 1) * HEADINGS] = 0
        reached = cost == 0
        for c in range(1, len(cost) + 1):
            reached = (cost < 0) & reached[after].any(axis=1)
            if not reached.any():
                break
            cost[reached] = c
        cost[cost < 0] = np.iinfo(np.int64).max // 2  # unreachable
        self._costs[goal] = cost.reshape(-1, HEADINGS)
        return self._costs[goal]

    def _ahead_label(self, pose: Pose) -> Label | None:
        front = ahead(self.view(pose))
        return front.label if front is not None else None

    def _walk_ends(self, pose: Pose, target: Label | None) -> int | None:
        """How many forward moves a Driver walking "until the wall" (or the target) makes from `pose`."""
        for moves in range(MAX_PLAN):
            obs = self.view(pose)
            if (near(obs, target) or obs.forward_blocked) if target is not None else at_wall(obs):
                return moves
            pose, collided = self.graph.moves.step(pose, Action.FORWARD)
            if collided:
                return None
        return None

"""A Commander that cheats: it is handed the Driver's true pose and the map, for measuring Drivers.

It plans each instruction with the fewest moves from the true pose (`sim.agents.route`), speaks one
instruction at a time in the scripted or the held-out phrasing, and waits for the Driver's answer;
when the Driver strays it plans again from where the Driver truly is. It confirms a claim
within 2 robot lengths of the target (the trial judge's rule) and rejects it otherwise. Never ranks
with agents: it sees what no Commander sees."""

from __future__ import annotations

import math

from sim.agents.route import Router
from sim.core.dynamics import Pose
from sim.core.geometry import SUCCESS_RADIUS_M
from sim.core.labels import Label, object_label
from sim.core.navgraph import NavGraph
from sim.core.observations import RayTable
from sim.language.phrases import Persona, PhraseKind, Phrases, Phrasing
from sim.language.vocab import OBJECT_WORDS
from sim.trial.agent import SeatInfo
from sim.trial.commands import Action, Judge, Say
from sim.trial.percepts import Claimed, Heard, Percept, PhaseBegan
from sim.trial.vocabulary import Phase, Role

THERE_M = 0.35  # the Commander says "you are there" this close to the target


class OracleCommander:
    """The Commander's seat agent for benches; `pose` is set by the harness before each percept."""

    def __init__(
        self,
        graph: NavGraph,
        rays: RayTable,
        targets: list[tuple[str, tuple[float, float]]],
        phrasing: Phrasing | Persona = Phrasing.SCRIPTED,
        seed: int = 0,
    ) -> None:
        self.graph, self.rays, self.targets = graph, rays, targets
        self.phrases = Phrases(phrasing, seed)
        self.router = Router(graph, rays, self.phrases)
        self.pose = Pose(0, 0)
        self._index: int | None = None

    def reset(self, info: SeatInfo) -> None:
        self._index = None

    def _target(self) -> tuple[str, Label, tuple[float, float], int]:
        assert self._index is not None  # only while navigating
        name, xy = self.targets[self._index]
        return name, object_label(name), xy, self.graph.nearest_node(*xy)

    def distance(self, pose: Pose) -> float:
        _, _, xy, _ = self._target()
        return float(math.dist(self.graph.nodes[pose.node], xy))

    def perceive(self, percept: Percept) -> list[Action]:
        if isinstance(percept, PhaseBegan):
            if percept.phase == Phase.LOCALIZING:
                return [Say(self.phrases.say(PhraseKind.ASK_VIEW))]
            if percept.phase == Phase.NAVIGATING and percept.target_index is not None:
                self._index = percept.target_index
                name = self._target()[0]
                return [
                    Say(
                        f"{self.phrases.say(PhraseKind.ANNOUNCE, thing=OBJECT_WORDS[object_label(name)])}. "
                        f"{self.instruction(plain=False)}"
                    )
                ]
            return []
        if isinstance(percept, Claimed):
            if self.distance(self.pose) <= SUCCESS_RADIUS_M:
                return [Judge(True)]
            return [Judge(False), Say(self.phrases.say(PhraseKind.REJECT))]
        if isinstance(percept, Heard) and percept.speaker == Role.DRIVER and self._index is not None:
            if "found" in percept.text:
                return []  # a claim is on its way
            return [Say(self.instruction(plain="?" in percept.text))]
        return []

    def instruction(self, plain: bool) -> str:
        """The next instruction from the true pose; `plain` (the Driver asked) counts steps."""
        _, label, _, goal = self._target()
        if self.distance(self.pose) <= THERE_M:
            return self.phrases.say(PhraseKind.THERE, thing=OBJECT_WORDS[label])
        return self.router.instruction(self.pose, label, goal, plain)

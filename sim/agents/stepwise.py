"""`StepwiseDriver`: the loop of a Driver agent that only moves and claims (the baselines, the
NDH model): it holds still until the Commander has marked it on the map and it has seen its
first frame, then decides one move on each frame after its move, and after a claim waits for the Commander's verdict. A subclass
decides (`decide`: a move, or None to claim) and may note what it perceives (`on_*`)."""

from __future__ import annotations

import re

from sim.agents.turns import (
    Claimed,
    DoClaim,
    DoMove,
    DoSay,
    Heard,
    Judged,
    Move,
    Moved,
    MoveResult,
    Percept,
    Phase,
    PhaseChanged,
    Saw,
    SeatInfo,
    Speaker,
    Turn,
)
from sim.core.labels import OBJECTS
from sim.robot.perception import RayObservation

_OBJECT_WORD = re.compile(rf"\b({'|'.join(OBJECTS)})s?\b", re.IGNORECASE)


class StepwiseDriver:
    def reset(self, info: SeatInfo) -> None:
        self.info = info
        self.phase = Phase.WAITING
        self.target_index: int | None = None
        self.dialog: list[tuple[Speaker, str]] = []
        self.rays: RayObservation | None = None
        self.seen = False  # no frame yet: nothing to drive by (a claim would have no frame either)
        self.moving = False  # a move asked for whose frame has not come yet
        self.claiming = False  # a claim asked for whose verdict has not come yet
        self.named: str | None = None  # the object the Commander named last, of those not found yet
        self.claimed_name: str | None = None
        self.found: set[str] = set()

    def perceive(self, percept: Percept) -> list[Turn]:
        match percept:
            case Heard(speaker=speaker, text=text):
                self.dialog.append((speaker, text))
                words = [w.lower() for w in _OBJECT_WORD.findall(text) if w.lower() not in self.found]
                if speaker == Speaker.COMMANDER and words:
                    self.named = words[-1]
            case PhaseChanged(phase=phase, target_index=index):
                self.phase = phase
                if index != self.target_index:
                    self.target_index = index
                    if self.named in self.found:
                        self.named = None
                    self.on_target()
            case Moved(move=move, result=result):
                if result != MoveResult.REFUSED:
                    self.on_moved(move, result)
                return []  # the frame after it is next (as it stands, for a move not made)
            case Saw(rays=rays):
                self.rays, self.moving, self.seen = rays, False, True
            case Claimed():
                self.claiming, self.claimed_name = True, self.named
            case Judged(confirmed=confirmed):
                self.claiming = False
                if confirmed:
                    if self.claimed_name is not None:
                        self.found.add(self.claimed_name)
                    return []  # the next target comes with the phase change
                self.on_rejected()
        return self._act()

    def _act(self) -> list[Turn]:
        if self.phase != Phase.NAVIGATING or not self.seen or self.moving or self.claiming:
            return []
        move = self.decide()
        if move is not None:
            self.moving = True
            return [DoMove(move)]
        self.claiming = True
        return [DoSay(self.claim_words()), DoClaim()]

    def claim_words(self) -> str:
        return f"I think I found the {self.named}" if self.named else "I think I found it"

    # -- what a subclass decides and notes -------------------------------------------------
    def decide(self) -> Move | None:
        raise NotImplementedError

    def on_target(self) -> None:
        """A new target (its number in `target_index`; its name only once the Commander says it)."""

    def on_moved(self, move: Move, result: MoveResult) -> None:
        """One of its moves was made (or bumped into a wall and left it where it was)."""

    def on_rejected(self) -> None:
        """The Commander rejected its claim."""

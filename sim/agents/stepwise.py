"""`StepwiseDriver`: the loop of a Driver agent that only moves and claims (the baselines, the
NDH model): it holds still until the Commander has marked it on the map and it has seen its
first frame, then decides one move on each frame after its move, and after a claim waits for the Commander's
verdict; a claim refused while the trial is paused it makes again once the trial runs. A subclass
decides (`decide`: a move, or None to claim) and may note what it perceives (`on_*`)."""

from __future__ import annotations

import re

from sim.core.labels import OBJECTS
from sim.core.rays import RayObservation
from sim.trial.agent import SeatInfo
from sim.trial.commands import Action, Claim, RequestMove, Say, named
from sim.trial.percepts import Claimed, Declined, Heard, Judged, Moved, PauseSet, Percept, PhaseBegan, Saw
from sim.trial.vocabulary import Move, Outcome, Phase, Role

_OBJECT_WORD = re.compile(rf"\b({'|'.join(OBJECTS)})s?\b", re.IGNORECASE)


class StepwiseDriver:
    def reset(self, info: SeatInfo) -> None:
        self.info = info
        self.phase = Phase.WAITING
        self.target_index: int | None = None
        self.dialog: list[tuple[Role, str]] = []
        self.rays: RayObservation | None = None
        self.seen = False  # no frame yet: nothing to drive by (a claim would have no frame either)
        self.moving = False  # a move asked for whose frame has not come yet
        self.claiming = False  # a claim asked for whose verdict has not come yet
        self.paused = False
        self.held = False  # a turn was refused: nothing more until the trial runs again or the Commander speaks
        self.claim_on_resume = False
        self.named: str | None = None  # the object the Commander named last, of those not found yet
        self.claimed_name: str | None = None
        self.found: set[str] = set()

    def perceive(self, percept: Percept) -> list[Action]:
        match percept:
            case Heard(speaker=speaker, text=text):
                self.dialog.append((speaker, text))
                words = [w.lower() for w in _OBJECT_WORD.findall(text) if w.lower() not in self.found]
                if speaker == Role.COMMANDER and words:
                    self.named = words[-1]
                if speaker == Role.COMMANDER and not self.paused:
                    self.held = False
            case PhaseBegan(phase=phase, target_index=index):
                self.phase, self.held = phase, False
                if index != self.target_index:
                    self.target_index = index
                    if self.named in self.found:
                        self.named = None
                    self.on_target()
            case Moved(move=move, result=result):
                if result != Outcome.REFUSED:
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
            case Declined():
                return self._refused(percept)
            case PauseSet(paused=paused):
                self.paused = paused
                if not paused:
                    self.held = False
                    if self.claim_on_resume:
                        self.claim_on_resume = False
                        return self._claim()
        return self._act()

    def _refused(self, refused: Declined) -> list[Action]:
        """A claim refused while paused is made again once the trial runs; any other refused
        turn it asks about, and it waits to be spoken to (no loop of refused turns)."""
        if isinstance(refused.action, Say):
            return []
        self.moving = self.claiming = False
        self.held = True
        if isinstance(refused.action, Claim) and self.paused:
            self.claim_on_resume = True
            return []
        return [Say(f"I could not {named(refused.action)} ({refused.reason}). What should I do?")]

    def _act(self) -> list[Action]:
        if self.phase != Phase.NAVIGATING or not self.seen or self.moving or self.claiming or self.held:
            return []
        move = self.decide()
        if move is not None:
            self.moving = True
            return [RequestMove(move)]
        return self._claim()

    def _claim(self) -> list[Action]:
        self.claiming = True
        return [Say(self.claim_words()), Claim()]

    def claim_words(self) -> str:
        return f"I think I found the {self.named}" if self.named else "I think I found it"

    # -- what a subclass decides and notes -------------------------------------------------
    def decide(self) -> Move | None:
        raise NotImplementedError

    def on_target(self) -> None:
        """A new target (its number in `target_index`; its name only once the Commander says it)."""

    def on_moved(self, move: Move, result: Outcome) -> None:
        """One of its moves was made (or bumped into a wall and left it where it was)."""

    def on_rejected(self) -> None:
        """The Commander rejected its claim."""

"""What an agent in a seat perceives: typed percepts, and `SeatView`, which says what one seat
learns of each event of the trial, as a person's page in that seat shows it.

An agent is woken by what a person in its seat would react to (a chat message, the frame after its
move, a judged claim, a phase change), never by a timer. The Commander never perceives a frame of
the stream, a move or a pose; the Driver never the map, the Commander's mark or a target's name.
"""

from __future__ import annotations

from dataclasses import dataclass

from sim.core.rays import RayObservation
from sim.trial import events as ev
from sim.trial.commands import Action
from sim.trial.state import TrialState
from sim.trial.vocabulary import FrameSource, Move, Outcome, Phase, Role


@dataclass(frozen=True)
class Heard:
    """Any chat message, the seat's own too."""

    speaker: Role
    text: str


@dataclass(frozen=True)
class Saw:
    """The Driver's frame: the simulator's rays at that frame, or perceived from a rover's pixels;
    None where unreadable. Driver seat only."""

    frame_id: int
    rays: RayObservation | None


@dataclass(frozen=True)
class Moved:
    move: Move
    result: Outcome
    reason: str | None = None


@dataclass(frozen=True)
class Claimed:
    """The Driver claimed. For the Commander, `rays`: the claim frame as its page shows it (None
    where unreadable); the Commander's only view through the camera."""

    target_index: int
    rays: RayObservation | None = None


@dataclass(frozen=True)
class Judged:
    confirmed: bool
    target_index: int


@dataclass(frozen=True)
class PhaseBegan:
    """`target`: the target's name, for the Commander's seat only, as its page learns each target
    when the trial reaches it."""

    phase: Phase
    target_index: int | None
    targets_total: int
    target: str | None = None


@dataclass(frozen=True)
class Declined:
    """One of the seat's actions was not allowed now, as a person's page shows an error. A move
    asked for and refused comes as `Moved` (result REFUSED), as the Driver's page hears it."""

    action: Action
    reason: str


@dataclass(frozen=True)
class PauseSet:
    """The trial paused (True) or runs again (False); moves and claims are refused while paused."""

    paused: bool


Percept = Heard | Saw | Moved | Claimed | Judged | PhaseBegan | Declined | PauseSet


class SeatView:
    """One seat's percepts of the trial's events, in the log's order. The Driver's frames come as
    its page shows them to a person who acts on them: the first once the trial runs, then the one
    that shows where each of its moves left the robot."""

    def __init__(self, role: Role, targets: list[str]) -> None:
        self.role, self.targets = role, targets
        self.phase: tuple[Phase, int | None] | None = None
        self.paused = False
        self.frames: dict[int, ev.FrameRecorded] = {}  # the latest Driver frames (a claim names one)
        self.latest: ev.FrameRecorded | None = None
        self.seen_first = False
        self.asked_ns: int | None = None  # the seat's move whose frame it has not seen: when asked
        self.outcome_ns: int | None = None  # and when its outcome was logged (None: not yet)

    @property
    def awaiting_frame(self) -> bool:
        """A move of this seat's has been asked for and the frame after it not perceived yet."""
        return self.asked_ns is not None

    def see(self, event: ev.Event, t_ns: int, state: TrialState) -> list[Percept]:
        """What this seat perceives of `event`, logged at `t_ns` (`state`: the trial after it)."""
        out: list[Percept] = []
        match event:
            case ev.Chat(role=role, text=text):
                out.append(Heard(role, text))
            case ev.PhaseChanged(phase=phase, target_index=index) if (phase, index) != self.phase:
                self.phase = (phase, index)
                target = None
                if self.role == Role.COMMANDER and phase.running and index is not None and index < len(self.targets):
                    target = self.targets[index]
                out.append(PhaseBegan(phase, index, len(self.targets), target))
                out += self._first_frame(state)
            case ev.TargetClaimed(target_index=index, frame_id=frame_id):
                frame = self.frames.get(frame_id)
                rays = frame.rays if frame is not None and self.role == Role.COMMANDER else None
                out.append(Claimed(index, rays))
            case ev.TargetConfirmed(target_index=index) | ev.TargetRejected(target_index=index):
                out.append(Judged(isinstance(event, ev.TargetConfirmed), index))
            case ev.FrameRecorded(source=FrameSource.DRIVER):
                self._keep(event)
                if self.role == Role.DRIVER:
                    out += self._first_frame(state) if not self.seen_first else self._after_move()
            case ev.MoveRequested() if self.role == Role.DRIVER:
                self.asked_ns, self.outcome_ns = t_ns, None
            case ev.MoveExecuted(action=move, outcome=outcome, reason=reason) if self.role == Role.DRIVER:
                out += self._moved(Moved(move, outcome, reason), t_ns)
        paused = bool(state.pause_reasons)
        if paused != self.paused and not state.over:  # the page shows the pause too
            self.paused = paused
            out.append(PauseSet(paused))
        return out

    def refused_as_asked(self, move: Move, reason: str, t_ns: int) -> list[Percept]:
        """The seat's move request refused as it came (no event of its own): the Driver hears why,
        and sees the frame as it stands, as its page shows them."""
        self.asked_ns = t_ns
        return self._moved(Moved(move, Outcome.REFUSED, reason), t_ns)

    def _keep(self, frame: ev.FrameRecorded) -> None:
        self.latest = frame
        self.frames[frame.frame_id] = frame
        for old in [k for k in self.frames if k < frame.frame_id - FRAMES_KEPT]:
            del self.frames[old]

    def _first_frame(self, state: TrialState) -> list[Percept]:
        if self.role != Role.DRIVER or self.seen_first or self.latest is None or not state.phase.running:
            return []
        return self._saw()

    def _moved(self, moved: Moved, t_ns: int) -> list[Percept]:
        """A move's outcome, then the frame after it where that came first (for a move not made,
        the frame as it stands: the robot did not move)."""
        if self.asked_ns is None:
            return [moved]
        self.outcome_ns = t_ns
        if moved.result == Outcome.REFUSED and self.latest is not None:
            return [moved, *self._saw()]
        return [moved, *self._after_move()]

    def _after_move(self) -> list[Percept]:
        """The latest frame where it shows where the pending move left the robot: the simulator
        draws one frame when a move ends (captured after it was asked for, rays attached); a rover
        streams, so its frame is the first captured once the move's outcome is logged."""
        frame, asked, done = self.latest, self.asked_ns, self.outcome_ns
        if frame is None or asked is None or done is None:
            return []
        return self._saw() if frame.capture_ns > (asked if frame.rays is not None else done) else []

    def _saw(self) -> list[Percept]:
        assert self.latest is not None
        self.seen_first, self.asked_ns, self.outcome_ns = True, None, None
        return [Saw(self.latest.frame_id, self.latest.rays)]


FRAMES_KEPT = 8  # Driver frames a seat keeps (with their rays) until a claim names one

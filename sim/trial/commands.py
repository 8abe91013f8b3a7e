"""What can happen to a trial, as the referee (`sim.trial.decide`) takes it.

A seat's `Action` is what a person's page or an agent in the seat does (the wire's messages
parse into them, `app.trial.messages.action_of`; an agent returns them from `perceive`); `Act` is
one, with the seat that took it and what only the server knows at that moment (`Now`). The other
commands come from the server: seats coming and going, a move the robot finished, timers, the
experimenter, a restart.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from sim.trial import events as ev
from sim.trial.vocabulary import Move, Outcome, Role


# -- a seat's actions --------------------------------------------------------------------
@dataclass(frozen=True)
class Say:
    text: str


@dataclass(frozen=True)
class RequestMove:
    """Driver: move the robot. `move_id` names it on the wire (one is drawn where none is given)."""

    move: Move
    move_id: str | None = None


@dataclass(frozen=True)
class Claim:
    """Driver: "I found the target"."""


@dataclass(frozen=True)
class Judge:
    """Commander: confirm or reject the pending claim."""

    confirmed: bool


@dataclass(frozen=True)
class Localize:
    """Commander: where the robot is, on the map."""

    x: float
    y: float
    heading: float | None = None


Action = Say | RequestMove | Claim | Judge | Localize


def named(action: Action) -> str:
    """The action's name, as a seat's page sends it (the wire message's `type`)."""
    match action:
        case Say():
            return "chat"
        case RequestMove():
            return "move"
        case Judge(confirmed=confirmed):
            return "confirm" if confirmed else "reject"
    return type(action).__name__.lower()


MAY: dict[Role, tuple[type, ...]] = {  # which seat may take which action
    Role.COMMANDER: (Say, Localize, Judge),
    Role.DRIVER: (Say, RequestMove, Claim),
}


@dataclass(frozen=True)
class Now:
    """What the referee takes from outside the log when a seat acts."""

    t_ns: int = 0
    robot_ready: bool = True  # a backend is in the robot seat
    min_move_interval_ns: int = 0
    within_m: float | None = None  # a claim judged: the robot's true distance from the target, where known


@dataclass(frozen=True)
class Act:
    role: Role
    action: Action
    now: Now = field(default_factory=Now)


# -- the server's commands ---------------------------------------------------------------
@dataclass(frozen=True)
class Join:
    role: Role


@dataclass(frozen=True)
class Leave:
    role: Role


@dataclass(frozen=True)
class FinishMove:
    move_id: str
    outcome: Outcome
    reason: str | None = None


@dataclass(frozen=True)
class AbandonMoves:
    """Moves that will never be finished (the server restarted, or the trial ended mid-move)."""

    reason: str


@dataclass(frozen=True)
class Note:
    """A fact from a sensor or a seat with no rule attached (frame, pose, bad message)."""

    event: ev.Event


@dataclass(frozen=True)
class Pause:
    note: str | None = None  # the experimenter's reason, logged and shown to the seats


@dataclass(frozen=True)
class Resume:
    pass


@dataclass(frozen=True)
class Abort:
    reason: str | None = None  # e.g. an agent's cap, logged with the phase change


@dataclass(frozen=True)
class GraceExpired:
    role: Role


@dataclass(frozen=True)
class JoinsDue:
    """A lobby's trial reached its join deadline (`TrialState.join_by_ns`)."""


@dataclass(frozen=True)
class Reopen:
    """A server opens a trial from its log: seats and moves of the process before are gone."""


Command = (
    Act | Join | Leave | FinishMove | AbandonMoves | Note | Pause | Resume | Abort | GraceExpired | JoinsDue | Reopen
)

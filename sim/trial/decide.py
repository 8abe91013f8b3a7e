"""`decide(state, command) -> events`: every rule of a trial, as a pure function.

The runtime turns what happens (a seat's message, a seat coming or going, a move the robot
finished, a timer, a server restart) into a command, records the events `decide` returns and
folds them into the state. A command that is not allowed now raises `Refused`, naming why in
words a participant can act on; nothing is recorded for it but the refusal.
"""

from __future__ import annotations

from sim.core.geometry import SUCCESS_RADIUS_M
from sim.trial import events as ev
from sim.trial.commands import (
    MAY,
    AbandonMoves,
    Abort,
    Act,
    Claim,
    Command,
    FinishMove,
    GraceExpired,
    Join,
    JoinsDue,
    Judge,
    Leave,
    Localize,
    Note,
    Now,
    Pause,
    Reopen,
    RequestMove,
    Resume,
    Say,
    named,
)
from sim.trial.specs import HUMAN
from sim.trial.state import TrialState
from sim.trial.vocabulary import EXPERIMENTER_PAUSE, Outcome, Phase, Role, disconnect_pause


class Refused(ValueError):
    """A command that is well formed but not allowed now; the message says why."""


# -- the rules ---------------------------------------------------------------------------
def decide(state: TrialState, command: Command) -> list[ev.Event]:
    match command:
        case Reopen():
            return _reopen(state)
        case AbandonMoves(reason=reason):
            return [_executed(state, move_id, Outcome.REFUSED, reason) for move_id in state.moves_in_flight]
        case FinishMove(move_id=move_id, outcome=outcome, reason=reason):
            return [_executed(state, move_id, outcome, reason)] if move_id in state.moves_in_flight else []
    if isinstance(command, Act):
        return _act(state, command)
    if state.over:
        return []
    match command:
        case Join(role=role):
            return _join(state, role)
        case Leave(role=role):
            return _leave(state, role)
        case Note(event=event):
            return [event]
        case Pause(note=note):
            return (
                [] if EXPERIMENTER_PAUSE in state.pause_reasons else [ev.Paused(reason=EXPERIMENTER_PAUSE, note=note)]
            )
        case Resume():
            return [ev.Resumed(reason=EXPERIMENTER_PAUSE)] if EXPERIMENTER_PAUSE in state.pause_reasons else []
        case Abort(reason=reason):
            return [ev.PhaseChanged(phase=Phase.ABORTED, reason=reason)]
        case GraceExpired(role=role):
            if role not in state.away:
                return []
            return [ev.PhaseChanged(phase=Phase.ABORTED, reason=f"the {role} was away longer than the grace period")]
        case JoinsDue():
            # A lobby paired the seats: one a person has not opened by the deadline aborts the
            # trial, saying whose (the lobby pairs again).
            people = [
                r for r, spec in ((Role.COMMANDER, state.commander), (Role.DRIVER, state.driver)) if spec == str(HUMAN)
            ]
            absent = [role for role in people if role not in state.joined]
            if state.phase != Phase.WAITING or not absent:
                return []
            return [
                ev.PhaseChanged(phase=Phase.ABORTED, reason=" and ".join(f"the {r}" for r in absent) + " never joined")
            ]
    raise TypeError(f"not a trial command: {command!r}")


def _act(state: TrialState, act: Act) -> list[ev.Event]:
    """A seat's action: its own seat's to take, and allowed now."""
    role, action = act.role, act.action
    if not isinstance(action, MAY.get(role, ())):
        raise Refused(f"the {role} may not send {named(action)!r} messages")
    if state.over:
        raise Refused(f"the trial is {state.phase}")
    match action:
        case Say(text=text):
            return [ev.Chat(role=role, text=text)]
        case RequestMove():
            return _request_move(state, action, act.now)
        case Localize(x=x, y=y, heading=heading):
            if not state.phase.running:
                raise Refused(f"the robot can be marked once the trial has started (it is {state.phase})")
            events: list[ev.Event] = [ev.Localized(x=x, y=y, heading=heading)]
            if state.phase == Phase.LOCALIZING:
                events.append(ev.PhaseChanged(phase=Phase.NAVIGATING, target_index=0))
            return events
        case Claim():
            return [_claim(state)]
        case Judge(confirmed=confirmed):
            return _judge(state, confirmed, act.now.within_m)
    raise TypeError(f"not a seat's action: {action!r}")


def _reopen(state: TrialState) -> list[ev.Event]:
    if state.over:
        return []  # a finished or aborted trial's log is closed
    events: list[ev.Event] = []
    if state.phase.running:  # the clock stopped at the last event; the seats now missing hold it
        events.append(
            ev.Restarted(
                paused=[
                    disconnect_pause(role)
                    for role in sorted(state.connected)
                    if disconnect_pause(role) not in state.pause_reasons
                ]
            )
        )
    events += decide(state, AbandonMoves("server restart"))
    events += [ev.Disconnected(role=role) for role in sorted(state.connected)]
    return events


def _join(state: TrialState, role: Role) -> list[ev.Event]:
    events: list[ev.Event] = [ev.Connected(role=role)]
    if disconnect_pause(role) in state.pause_reasons:
        events.append(ev.Resumed(reason=disconnect_pause(role)))
    connected = state.connected | {role}
    if state.phase == Phase.WAITING and all(r in connected for r in state.seats_needed):
        events.append(ev.PhaseChanged(phase=Phase.LOCALIZING, target_index=0))
    return events


def _leave(state: TrialState, role: Role) -> list[ev.Event]:
    events: list[ev.Event] = [ev.Disconnected(role=role)]
    if state.phase.running and disconnect_pause(role) not in state.pause_reasons:
        events.append(ev.Paused(reason=disconnect_pause(role)))
    return events


def why_not_running(state: TrialState) -> str:
    if state.waiting_for:
        return f"the trial is waiting for the {' and the '.join(state.waiting_for)} to connect"
    if disconnect_pause(Role.ROBOT) in state.pause_reasons:
        return "the trial is paused: the robot is not connected"
    return "the trial is paused" if state.pause_reasons else f"the trial is {state.phase}"


def _request_move(state: TrialState, request: RequestMove, now: Now) -> list[ev.Event]:
    move_id, action = request.move_id or f"auto-{len(state.move_ids) + 1}", request.move
    if move_id in state.move_ids:
        raise Refused(f"move {move_id!r} was already received; it is not executed twice")
    reason = None
    if not state.running:
        reason = why_not_running(state)
    elif state.moves_in_flight:
        reason = "the previous move is still executing"
    elif state.last_move_ns is not None and now.t_ns - state.last_move_ns < now.min_move_interval_ns:
        reason = "too soon after the previous move"
    elif not now.robot_ready:
        reason = "the robot is not connected"
    if reason is not None:  # nothing moves and no move id is spent; the runtime counts it in its run
        return [ev.MovesRefused(reason=reason)]
    return [ev.MoveRequested(move_id=move_id, action=action)]


def _executed(state: TrialState, move_id: str, outcome: Outcome, reason: str | None) -> ev.MoveExecuted:
    """A move in flight finished (or never will: refused)."""
    action, _ = state.moves_in_flight[move_id]
    collision = outcome == Outcome.COLLISION
    return ev.MoveExecuted(move_id=move_id, action=action, outcome=outcome, collision=collision, reason=reason)


def _claim(state: TrialState) -> ev.TargetClaimed:
    if state.phase != Phase.NAVIGATING or state.pause_reasons:
        raise Refused(
            "a target can be claimed once the Commander has marked the robot on the map, "
            "and not while the trial is paused"
        )
    if state.pending_claim is not None:
        raise Refused("the previous claim is still waiting for the Commander")
    if state.last_frame_id is None:
        raise Refused("there is no camera frame to send yet")
    target = state.current_target
    if target is None:  # never while navigating; the check gives the event its str
        raise Refused("there is no target left to claim")
    return ev.TargetClaimed(target=target, target_index=state.target_index, frame_id=state.last_frame_id)


def _judge(state: TrialState, confirmed: bool, within_m: float | None) -> list[ev.Event]:
    claim = state.pending_claim
    if claim is None:
        raise Refused("there is no claimed target to confirm or reject")
    target, index = claim.target, claim.target_index
    truly = None if within_m is None else within_m <= SUCCESS_RADIUS_M
    verdict = ev.TargetConfirmed if confirmed else ev.TargetRejected
    events: list[ev.Event] = [verdict(target=target, target_index=index, within_m=within_m, truly_within=truly)]
    if confirmed:
        last = index + 1 >= len(state.targets)
        events.append(ev.PhaseChanged(phase=Phase.FINISHED if last else Phase.NAVIGATING, target_index=index + 1))
    return events

"""What each seat is allowed to hear of an event, and the status every seat is kept up to date with.

The Commander never gets camera frames, moves or the true pose; the Driver never gets the
map, the Commander's localization or the target images; neither gets the simulator's
ground truth on a confirmation. The experimenter's live view hears everything but the
overhead camera (that is for annotation and replay), ground truth included.
"""

from __future__ import annotations

import base64
from collections.abc import Callable, Iterable

from app.trial.messages import EventMessage, Message, Photo, ServerMessage, StatusMessage, TrialSnapshot, WelcomeMessage
from sim.trial import events as ev
from sim.trial.events import LoggedEvent
from sim.trial.state import TrialState
from sim.trial.vocabulary import FrameSource, Phase, Role

JpegOf = Callable[[int], bytes | None]  # a frame's image by its frame id (None: not stored)
HISTORY: tuple[type[ev.Event], ...] = (ev.Chat, ev.PhaseChanged, ev.TargetConfirmed, ev.TargetRejected)

EXPERIMENTER = "experimenter"  # the role of an experimenter's live view (not a seat of the trial)

SHARED: set[type[ev.Event]] = {
    ev.Chat,
    ev.PhaseChanged,
    ev.Paused,
    ev.Resumed,
    ev.Connected,
    ev.Disconnected,
    ev.TargetClaimed,
    ev.TargetConfirmed,
    ev.TargetRejected,
}
SEES: dict[str, set[type[ev.Event]]] = {
    Role.COMMANDER: SHARED | {ev.Localized},
    Role.DRIVER: SHARED | {ev.MoveExecuted, ev.FrameRecorded},
    EXPERIMENTER: SHARED
    | {
        ev.Localized,
        ev.MoveRequested,
        ev.MoveExecuted,
        ev.MovesRefused,
        ev.FrameRecorded,
        ev.PoseSampled,
        ev.BadMessage,
        ev.Restarted,
    },
}
VISIBLE = {role: frozenset(model.kind for model in models) for role, models in SEES.items()}  # by logged kind

GROUND_TRUTH = ("within_m", "truly_within")


def view(role: str, event: LoggedEvent) -> EventMessage | None:
    """The message a seat gets for `event`, or None when it must not see it."""
    if event.kind not in VISIBLE.get(role, ()):
        return None
    if event.is_(ev.FrameRecorded) and event.payload.get("source", FrameSource.DRIVER) != FrameSource.DRIVER:
        return None  # the overhead camera is for annotation and replay, never for a live view
    payload = (
        dict(event.payload)
        if role == EXPERIMENTER
        else {k: v for k, v in event.payload.items() if k not in GROUND_TRUTH}
    )
    if event.is_(ev.FrameRecorded):
        payload.pop("path", None)
    return {"type": ServerMessage.EVENT, "seq": event.seq, "kind": event.kind, "t_ns": event.t_ns, "payload": payload}


CLOCK_FIELDS = ("elapsed_s", "join_left_s")  # figures of the moment of sending, which pages run on themselves


def status_of(state: TrialState, now_ns: int) -> StatusMessage:
    """What every seat shows of where the trial stands (docs/platform.md, "status"). Sent after
    each event that changes any field but the clocks; pages run the clocks themselves."""
    join_left_s = None
    if state.phase == Phase.WAITING and state.join_by_ns is not None:  # a study's pairing: seats not all opened
        join_left_s = round(max(0.0, (state.join_by_ns - now_ns) / 1e9), 1)
    return {
        "type": ServerMessage.STATUS,
        "phase": str(state.phase),
        "target_index": state.target_index,
        "targets_total": len(state.targets),
        "elapsed_s": round(state.active_s(now_ns), 3),
        "running": state.running,
        "moves": state.moves,
        "paused": sorted(state.pause_reasons),
        "waiting_for": [str(r) for r in state.waiting_for],
        "abort_reason": state.abort_reason,
        "pause_note": state.pause_note,
        "claim_pending": state.pending_claim is not None,  # the Commander has a claim to decide
        "join_left_s": join_left_s,  # seconds until a seat still unopened calls the trial off
    }


def claim_attachment(frame_id: int, jpeg_of: JpegOf) -> Photo:
    """The frame a claim was made on, for the Commander to judge."""
    jpeg = jpeg_of(frame_id)
    return {"frame_id": frame_id, "jpeg": base64.b64encode(jpeg).decode() if jpeg else None}


def welcome(
    role: str,
    trial_id: int,
    state: TrialState,
    connected: Iterable[str],
    events: Iterable[LoggedEvent],
    status: StatusMessage,
    jpeg_of: JpegOf,
) -> WelcomeMessage:
    """What a seat (or the experimenter's watch) gets on joining: where the trial stands, the
    dialog so far as this role may hear it, and what only this role sees (the Commander's target,
    mark and pending claim; the Driver's last frame; the experimenter's pose, targets and estimate)."""
    s = state
    message: WelcomeMessage = {
        "type": ServerMessage.WELCOME,
        "role": role,
        "trial_id": trial_id,
        "phase": s.phase,
        "target_index": s.target_index,
        "targets_total": len(s.targets),
        "connected": sorted(connected),
        "seats_needed": list(s.seats_needed),
        "paused": sorted(s.pause_reasons),
        "pending_claim": s.pending_claim is not None,
        "last_seq": s.last_seq,
        "history": [msg for e in events if e.is_(*HISTORY) and (msg := view(role, e)) is not None],
        "status": status,
    }
    mark = s.localization.payload() if s.localization else None
    if role == Role.COMMANDER:
        message["target"] = s.current_target
        message["localization"] = mark  # their own mark, for a window opened later
        if s.pending_claim is not None:
            message["claim"] = claim_attachment(s.pending_claim.frame_id, jpeg_of)
    if role in (Role.DRIVER, EXPERIMENTER) and s.last_frame_id is not None:
        jpeg = jpeg_of(s.last_frame_id)
        if jpeg is not None:
            message["frame"] = {"frame_id": s.last_frame_id, "jpeg": base64.b64encode(jpeg).decode()}
    if role == EXPERIMENTER:
        message["pose"] = s.pose
        message["targets"] = list(s.targets)
        message["localization"] = mark
    return message


def snapshot(
    trial_id: int, state: TrialState, now_ns: int, connected: Iterable[str], belief: Message | None
) -> TrialSnapshot:
    """One live trial on the experimenter's dashboard (`/experimenter/api/trials`)."""
    s, here = state, set(connected)
    return {
        "trial_id": trial_id,
        "phase": s.phase,
        "target_index": s.target_index,
        "target": s.current_target,
        "elapsed_s": round(s.active_s(now_ns), 1),
        "moves": s.moves,
        "collisions": s.collisions,
        "pose": s.pose,
        "paused": sorted(s.pause_reasons),
        "pause_note": s.pause_note,
        "seats": {r: r in here for r in s.seats_needed},
        "waiting_for": [str(r) for r in s.waiting_for],
        "backend": s.backend,
        "localization": s.localization.payload() if s.localization else None,
        "maze": s.maze,
        "belief": belief,
    }

"""What each seat is allowed to hear of an event, and the status every seat is kept up to date with.

The Commander never gets camera frames, moves or the true pose; the Driver never gets the
map, the Commander's localization or the target images; neither gets the simulator's
ground truth on a confirmation. The experimenter's live view hears everything but the
overhead camera (that is for annotation and replay), ground truth included.
"""

from __future__ import annotations

from typing import Any

from app.trial import events as ev
from app.trial.events import LoggedEvent
from app.trial.state import TrialState
from app.trial.vocabulary import FrameSource, Role

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
    | {ev.Localized, ev.MoveRequested, ev.MoveExecuted, ev.FrameRecorded, ev.PoseSampled, ev.BadMessage, ev.Restarted},
}
VISIBLE = {role: frozenset(model.kind for model in models) for role, models in SEES.items()}  # by logged kind

GROUND_TRUTH = ("within_m", "truly_within")


def view(role: str, event: LoggedEvent) -> dict[str, Any] | None:
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
    return {"type": "event", "seq": event.seq, "kind": event.kind, "t_ns": event.t_ns, "payload": payload}


def status_of(state: TrialState, now_ns: int) -> dict[str, Any]:
    """What every seat shows of where the trial stands (docs/protocol.md, "status"). Sent after
    each event that changes any field but the clock; pages run the clock themselves while running."""
    return {
        "type": "status",
        "phase": str(state.phase),
        "target_index": state.target_index,
        "targets_total": len(state.targets),
        "elapsed_s": round(state.active_s(now_ns), 3),
        "running": state.running,
        "moves": state.moves,
        "paused": sorted(state.pause_reasons),
        "waiting_for": [str(r) for r in state.waiting_for],
        "claim_pending": state.pending_claim is not None,  # the Commander has a claim to decide
    }

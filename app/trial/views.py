"""What each seat is allowed to hear of an event, and the status every seat is kept up to date with.

The Commander never gets camera frames, moves or the true pose; the Driver never gets the
map, the Commander's localization or the target images; neither gets the simulator's
ground truth on a confirmation. The experimenter's live view hears everything but the
overhead camera (that is for annotation and replay), ground truth included.
"""

from __future__ import annotations

from typing import Any

from app.trial.events import LoggedEvent
from app.trial.state import TrialState
from app.trial.vocabulary import FrameSource, Role

EXPERIMENTER = "experimenter"  # the role of an experimenter's live view (not a seat of the trial)

SHARED = {
    "chat",
    "phase",
    "paused",
    "resumed",
    "connect",
    "disconnect",
    "target_claimed",
    "target_confirmed",
    "target_rejected",
}
VISIBLE = {
    Role.COMMANDER: SHARED | {"localization"},
    Role.DRIVER: SHARED | {"move_executed", "frame"},
    EXPERIMENTER: SHARED
    | {"localization", "move_requested", "move_executed", "frame", "pose", "bad_message", "restarted"},
}
GROUND_TRUTH = ("within_m", "truly_within")


def view(role: str, event: LoggedEvent) -> dict[str, Any] | None:
    """The message a seat gets for `event`, or None when it must not see it."""
    if event.kind not in VISIBLE.get(role, ()):
        return None
    if event.kind == "frame" and event.payload.get("source", FrameSource.DRIVER) != FrameSource.DRIVER:
        return None  # the overhead camera is for annotation and replay, never for a live view
    payload = (
        dict(event.payload)
        if role == EXPERIMENTER
        else {k: v for k, v in event.payload.items() if k not in GROUND_TRUTH}
    )
    if event.kind == "frame":
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

"""What each seat is allowed to hear of an event.

The Commander never gets camera frames, moves or the true pose; the Driver never gets the
map, the Commander's localization or the target images; neither gets the simulator's
ground truth on a confirmation (the experimenter's dashboard reads it from the log).
"""

from __future__ import annotations

from typing import Any

from app.trial.state import LoggedEvent

SHARED = {"chat", "phase", "paused", "resumed", "connect", "disconnect",
          "target_claimed", "target_confirmed", "target_rejected"}
VISIBLE = {
    "commander": SHARED | {"localization"},
    "driver": SHARED | {"move_executed", "frame"},
}
GROUND_TRUTH = ("within_m", "truly_within")


def view(role: str, event: LoggedEvent) -> dict[str, Any] | None:
    """The message a seat gets for `event`, or None when it must not see it."""
    if event.kind not in VISIBLE.get(role, ()):
        return None
    if event.kind == "frame" and event.payload.get("source", "driver") != "driver":
        return None  # the overhead camera is for annotation and replay, never for a seat
    payload = {k: v for k, v in event.payload.items() if k not in GROUND_TRUTH}
    if event.kind == "frame":
        payload.pop("path", None)
    return {"type": "event", "seq": event.seq, "kind": event.kind, "t_ns": event.t_ns, "payload": payload}

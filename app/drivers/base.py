"""`DriverPolicy`: an agent in the Driver's seat.

It sees what a human Driver sees: the dialog so far and the latest camera frame. The
observation also carries the target the trial is on and, where the robot backend knows it,
the true pose, which only oracle baselines may use.

    reset(info)                    info: {"trial_id", "maze", "targets", "backend"}
    act(dialog, observation) -> "forward" | "left" | "right" | "stop"
        dialog:      [{"role": "commander"|"driver", "text": str}, ...] in order
        observation: {"frame": bytes (JPEG) | None, "frame_id": int | None,
                      "target": str, "target_index": int,
                      "pose": (x, y, theta) | None,
                      "rejected": int (claims of this target the Commander rejected),
                      where the pose is None and the trial's particle filter runs (a rover):
                      "rays": (OBS_FEATURES,) float32 perceived from the frame after the last
                              move, in `RayTable.features` layout,
                      "belief": {"x", "y", "heading", "spread_m"} (the filter's mean)}

"stop" means "I think I found the target": the seat claims it, and the policy acts again
once the Commander has confirmed (next target) or rejected (same target) the claim.
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

from app.trial.vocabulary import MoveAction

DRIVER_ACTIONS = (*(str(a) for a in MoveAction), "stop")


@runtime_checkable
class DriverPolicy(Protocol):
    def reset(self, info: dict[str, Any]) -> None: ...

    def act(self, dialog: list[dict[str, str]], observation: dict[str, Any]) -> str: ...

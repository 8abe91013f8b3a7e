"""What a front-camera frame says in the simulator's terms: the 13 rays' labels and depths.

The simulator's ray table gives it for a pose; `sim.robot.perception` reads it from pixels. It is
what a Driver's seat perceives of a frame, so it sits below everything that hands it on.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np


class FrameProblem(StrEnum):
    DARK = "dark"
    OVEREXPOSED = "overexposed"


@dataclass(frozen=True, eq=False)
class RayObservation:
    """What the camera says about the 13 rays, in the simulator's terms."""

    labels: np.ndarray  # (13,) uint8 Label; FLOOR where nothing was met (or not valid)
    depth: np.ndarray  # (13,) float32 metres
    too_close: np.ndarray  # (13,) bool
    valid: np.ndarray  # (13,) bool: the ray's colour was recognised and its depth measured
    forward_blocked: bool
    problem: FrameProblem | None = None  # the whole frame was unreadable

    @property
    def confidence(self) -> float:
        """Fraction of rays read; 0 for an unreadable frame."""
        return float(self.valid.mean())

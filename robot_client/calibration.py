"""Motor wiring and move timings of one rover, read from and written to a JSON file.

A move is a timed pulse: both motors forward for `forward_s` to advance 0.07 m, or in opposite
directions for `left_s` / `right_s` to turn 45 degrees. `robotslang-robot calibrate` measures
these on the table and writes the file.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, fields
from pathlib import Path

FORWARD_M = 0.07
TURN_DEG = 45.0


class CalibrationError(ValueError):
    """The calibration file is missing, unreadable or has a bad value; the text says which."""


@dataclass(frozen=True)
class Calibration:
    # BCM pin numbers of the motor driver (e.g. an L298N's IN1..IN4), PWM-driven.
    left_forward_pin: int = 4
    left_backward_pin: int = 14
    right_forward_pin: int = 17
    right_backward_pin: int = 18
    forward_speed: float = 0.6
    turn_speed: float = 0.6
    forward_s: float = 0.35
    left_s: float = 0.40
    right_s: float = 0.40
    # No pulse may run longer than this, whatever the timings say.
    max_move_s: float = 2.0

    def __post_init__(self) -> None:
        pins = [self.left_forward_pin, self.left_backward_pin, self.right_forward_pin, self.right_backward_pin]
        for name in ("left_forward_pin", "left_backward_pin", "right_forward_pin", "right_backward_pin"):
            value = getattr(self, name)
            if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value <= 27:
                raise CalibrationError(f"{name} must be a BCM GPIO number 0..27, got {value!r}")
        if len(set(pins)) != 4:
            raise CalibrationError(f"the four motor pins must differ, got {pins}")
        for name in ("forward_speed", "turn_speed"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not 0 < value <= 1:
                raise CalibrationError(f"{name} must be in (0, 1], got {value!r}")
        if not isinstance(self.max_move_s, (int, float)) or not 0 < self.max_move_s <= 10:
            raise CalibrationError(f"max_move_s must be in (0, 10] seconds, got {self.max_move_s!r}")
        for name in ("forward_s", "left_s", "right_s"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not 0 < value <= self.max_move_s:
                raise CalibrationError(f"{name} must be in (0, max_move_s={self.max_move_s}] seconds, got {value!r}")

    def duration(self, action: str) -> float:
        """Seconds of motor pulse for one move, never above max_move_s."""
        return min({"forward": self.forward_s, "left": self.left_s, "right": self.right_s}[action], self.max_move_s)

    @classmethod
    def load(cls, path: Path) -> Calibration:
        try:
            data = json.loads(Path(path).read_text())
        except FileNotFoundError:
            raise CalibrationError(
                f"calibration file {path} does not exist (create it with `robotslang-robot calibrate`)"
            ) from None
        except (OSError, json.JSONDecodeError) as exc:
            raise CalibrationError(f"calibration file {path} is not readable JSON: {exc}") from None
        if not isinstance(data, dict):
            raise CalibrationError(f"calibration file {path} must hold a JSON object")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise CalibrationError(
                f"calibration file {path} has unknown keys {unknown}; known keys are {sorted(known)}"
            )
        try:
            return cls(**data)
        except CalibrationError as exc:
            raise CalibrationError(f"calibration file {path}: {exc}") from None

    def save(self, path: Path) -> None:
        Path(path).write_text(json.dumps(asdict(self), indent=2) + "\n")

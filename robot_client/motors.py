"""The rover's two motors, driven through gpiozero.

`gpio` uses the Pi's default pin factory; `mock` uses gpiozero's MockFactory with PWM pins, so
everything above this module (moves, watchdog, shutdown) runs unchanged off the Pi and the pin
states can be read back. With a pin log, every pin change is appended as a JSON line with the
machine's monotonic clock, so another process (a test, a person) can check what the motors did.
"""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path
from typing import Protocol

from gpiozero import Motor, Robot

from robot_client.calibration import Calibration


class MotorDriver(Protocol):
    """What the link drives a move with: the rover's `Motors`, or a simulated rover's."""

    @property
    def calibration(self) -> Calibration: ...

    @property
    def running(self) -> bool: ...

    def start(self, action: str) -> None: ...

    def stop(self) -> None: ...

    def close(self) -> None: ...


class MotorError(RuntimeError):
    """The motors could not be set up (no GPIO access, pins in use); the text says why."""


class Motors:
    """Start a move's pulse, stop. Safe to call stop() any number of times, from any thread."""

    def __init__(self, calibration: Calibration, pin_factory=None) -> None:
        self.calibration = calibration
        c = calibration
        try:
            self._robot = Robot(
                left=Motor(c.left_forward_pin, c.left_backward_pin, pwm=True, pin_factory=pin_factory),
                right=Motor(c.right_forward_pin, c.right_backward_pin, pwm=True, pin_factory=pin_factory),
                pin_factory=pin_factory,
            )
        except Exception as exc:  # gpiozero raises many kinds; all mean "cannot drive these pins"
            raise MotorError(
                f"cannot open motor pins {c.left_forward_pin},{c.left_backward_pin},"
                f"{c.right_forward_pin},{c.right_backward_pin}: {exc}"
            ) from exc
        self._lock = threading.Lock()

    def start(self, action: str) -> None:
        c = self.calibration
        with self._lock:
            if action == "forward":
                self._robot.forward(c.forward_speed)
            elif action == "left":
                self._robot.left(c.turn_speed)
            elif action == "right":
                self._robot.right(c.turn_speed)
            else:
                raise ValueError(f"unknown move {action!r}")

    def stop(self) -> None:
        with self._lock:
            self._robot.stop()

    @property
    def running(self) -> bool:
        return self._robot.value != (0, 0)

    def close(self) -> None:
        self.stop()
        self._robot.close()


def mock_factory(pin_log: Path | None = None):
    """gpiozero's MockFactory with PWM pins; with `pin_log`, pin changes go to that file."""
    from gpiozero.pins.mock import MockFactory, MockPWMPin

    if pin_log is None:
        return MockFactory(pin_class=MockPWMPin)
    log_path = pin_log  # a name the closure below sees as a Path

    class LoggedPWMPin(MockPWMPin):
        def _change_state(self, value):
            changed = super()._change_state(value)
            if changed:
                # Opened per change (a few per move): readers see each line at once, and no
                # handle outlives the pins, whoever closes them and whenever.
                with open(log_path, "a") as log:
                    log.write(
                        json.dumps({"t_ns": time.monotonic_ns(), "pin": self.info.name, "state": float(value)}) + "\n"
                    )
            return changed

    return MockFactory(pin_class=LoggedPWMPin)


def open_motors(kind: str, calibration: Calibration, pin_log: Path | None = None) -> Motors:
    if kind == "mock":
        return Motors(calibration, mock_factory(pin_log))
    if kind == "gpio":
        if pin_log is not None:
            raise MotorError("--pin-log records mock pins only; use it with --motors mock")
        return Motors(calibration)
    raise MotorError(f"--motors must be gpio or mock, got {kind!r}")

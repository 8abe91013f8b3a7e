"""`robotslang-robot calibrate`: find the pulse lengths for a 0.07 m step and 45 degree turns.

The person places the rover on the table, the rover runs one pulse, the person measures what
happened; the pulse is scaled by target / measured and tried again until the person accepts it.
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

from robot_client.calibration import FORWARD_M, TURN_DEG, Calibration
from robot_client.motors import Motors, open_motors

STEPS = (
    ("forward", "forward_s", "How far did it move, in centimetres?", FORWARD_M * 100, "cm"),
    ("left", "left_s", "How many degrees did it turn left?", TURN_DEG, "degrees"),
    ("right", "right_s", "How many degrees did it turn right?", TURN_DEG, "degrees"),
)


def pulse(motors: Motors, action: str, seconds: float) -> None:
    motors.start(action)
    try:
        time.sleep(seconds)
    finally:
        motors.stop()


def calibrate(motors: Motors, calibration: Calibration, ask=input, say=print) -> Calibration:
    """Walk a person through the three moves; return the calibration with measured pulse lengths."""
    for action, field, question, target, unit in STEPS:
        seconds = getattr(calibration, field)
        say(f"\n== {action}: target {target:g} {unit} ==")
        while True:
            ask(f"Place the rover with room to move, then press Enter to run a {seconds:.3f} s pulse.")
            pulse(motors, action, seconds)
            answer = ask(f"{question} (target {target:g}; press Enter to accept {seconds:.3f} s) ").strip()
            if not answer:
                break
            try:
                measured = float(answer)
            except ValueError:
                say(f"'{answer}' is not a number; measure again.")
                continue
            if measured <= 0:
                say("The rover must have moved; check the wiring and the speed, then try again.")
                continue
            proposed = seconds * target / measured
            if proposed > calibration.max_move_s:
                say(
                    f"That needs {proposed:.2f} s, more than max_move_s={calibration.max_move_s} s; "
                    "raise the speed in the file instead."
                )
                continue
            seconds = proposed
        calibration = replace(calibration, **{field: round(seconds, 4)})
    return calibration


def run(
    motors_kind: str, path: Path, left_pins: tuple[int, int] | None, right_pins: tuple[int, int] | None
) -> Calibration:
    calibration = Calibration.load(path) if path.exists() else Calibration()
    if left_pins:
        calibration = replace(calibration, left_forward_pin=left_pins[0], left_backward_pin=left_pins[1])
    if right_pins:
        calibration = replace(calibration, right_forward_pin=right_pins[0], right_backward_pin=right_pins[1])
    motors = open_motors(motors_kind, calibration)
    try:
        calibration = calibrate(motors, calibration)
    finally:
        motors.close()
    path.parent.mkdir(parents=True, exist_ok=True)
    calibration.save(path)
    print(f"\nWrote {path}")
    return calibration

"""The motors on gpiozero's MockFactory: the pins a real motor driver would see."""

import json
import time

import pytest

from robot_client.calibration import Calibration, CalibrationError
from robot_client.motors import MotorError, Motors, mock_factory, open_motors

PINS = Calibration(
    left_forward_pin=5,
    left_backward_pin=6,
    right_forward_pin=13,
    right_backward_pin=19,
    forward_speed=0.7,
    turn_speed=0.5,
)


def pin_values(factory) -> dict[str, float]:
    return {info.name: float(pin.state) for info, pin in factory.pins.items()}


@pytest.mark.parametrize(
    "action, expected",
    [
        ("forward", {"GPIO5": 0.7, "GPIO6": 0.0, "GPIO13": 0.7, "GPIO19": 0.0}),
        ("left", {"GPIO5": 0.0, "GPIO6": 0.5, "GPIO13": 0.5, "GPIO19": 0.0}),
        ("right", {"GPIO5": 0.5, "GPIO6": 0.0, "GPIO13": 0.0, "GPIO19": 0.5}),
    ],
)
def test_each_move_drives_the_calibrated_pins(action, expected):
    factory = mock_factory()
    motors = Motors(PINS, factory)
    motors.start(action)
    assert pin_values(factory) == expected and motors.running
    motors.stop()
    assert set(pin_values(factory).values()) == {0.0} and not motors.running
    motors.close()


def test_unknown_move_is_refused_without_touching_pins():
    factory = mock_factory()
    motors = Motors(PINS, factory)
    with pytest.raises(ValueError, match="unknown move 'backward'"):
        motors.start("backward")
    assert set(pin_values(factory).values()) == {0.0}


def test_pin_log_records_every_change_with_the_monotonic_clock(tmp_path):
    log = tmp_path / "pins.jsonl"
    before = time.monotonic_ns()
    motors = open_motors("mock", PINS, log)
    motors.start("forward")
    time.sleep(0.05)
    motors.stop()
    lines = [json.loads(line) for line in log.read_text().splitlines()]
    assert [(e["pin"], e["state"]) for e in lines] == [("GPIO5", 0.7), ("GPIO13", 0.7), ("GPIO5", 0.0), ("GPIO13", 0.0)]
    assert before <= lines[0]["t_ns"] and lines[2]["t_ns"] - lines[1]["t_ns"] >= 50e6


def test_pin_log_is_for_mock_motors_only(tmp_path):
    with pytest.raises(MotorError, match="--pin-log records mock pins only"):
        open_motors("gpio", PINS, tmp_path / "pins.jsonl")


def test_calibration_round_trip_and_named_errors(tmp_path):
    path = tmp_path / "cal.json"
    PINS.save(path)
    assert Calibration.load(path) == PINS
    assert PINS.duration("forward") == PINS.forward_s

    path.write_text('{"forward_s": 5.0}')
    with pytest.raises(CalibrationError, match=r"cal.json: forward_s must be in \(0, max_move_s=2.0\]"):
        Calibration.load(path)
    path.write_text('{"left_forward_pin": 4, "left_backward_pin": 4}')
    with pytest.raises(CalibrationError, match="pins must differ"):
        Calibration.load(path)
    path.write_text('{"speed": 1}')
    with pytest.raises(CalibrationError, match=r"unknown keys \['speed'\]"):
        Calibration.load(path)
    path.write_text("not json")
    with pytest.raises(CalibrationError, match="not readable JSON"):
        Calibration.load(path)
    with pytest.raises(CalibrationError, match="robotslang-robot calibrate"):
        Calibration.load(tmp_path / "absent.json")

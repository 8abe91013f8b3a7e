"""`agent:dialog`: the Driver that takes part in the dialog (`sim.agents.dialog_driver`) in the
Driver's seat: it answers, waits for instructions, follows them, reports and claims."""

from __future__ import annotations

from app.drivers.base import Seating
from app.drivers.registry import DriverParts
from sim.agents.dialog_driver import DialogDriver


def dialog_driver(parts: DriverParts, seating: Seating) -> DialogDriver:
    return DialogDriver(seed=seating.seed)

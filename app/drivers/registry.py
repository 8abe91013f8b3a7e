"""Driver agents by spec: a trial's `driver` is `human`, `agent:<name>` or `oracle:<name>`.

A driver is a factory, `factory(parts, seating) -> Agent` (`sim.agents.turns.Agent`; parts:
`DriverParts`, the settings and the mazes with their cached graphs; seating:
`app.drivers.base.Seating`, whose `oracle` is set for `oracle:` drivers only), and optionally a
check, `check(parts) -> reason | None`, saying why it cannot start now (None: it can). The built-in ones are named here by
"module:function" and imported on first look-up, so the learned ones import torch only when
they are checked or seated; `register_driver` adds more.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from app.clock import ServerClock
from app.drivers.base import Seating
from app.mazes import Mazes
from app.settings import Settings
from app.trial.specs import SeatSpec
from sim.agents.turns import Agent


@dataclass(frozen=True)
class DriverParts:
    """What agent Drivers, their checks and their seats use of the server."""

    settings: Settings
    mazes: Mazes
    clock: ServerClock
    driver_checks: dict[Any, str | None] = field(default_factory=dict)  # agents' start checks, by file version


DriverFactory = Callable[[DriverParts, Seating], Agent]
DriverCheck = Callable[[DriverParts], "str | None"]

BUILTIN = {
    "agent:random": ("app.drivers.baselines:random_driver", None),
    "agent:dialog": ("app.drivers.dialog:dialog_driver", None),
    "agent:seq2seq": ("app.drivers.seq2seq:seq2seq_driver", "app.drivers.seq2seq:seq2seq_check"),
    "oracle:shortest": ("app.drivers.baselines:shortest_driver", None),
}


@dataclass(frozen=True)
class DriverEntry:
    factory: DriverFactory
    check: DriverCheck | None = None


_REGISTERED: dict[str, DriverEntry] = {}


def is_driver_spec(spec: str) -> bool:
    try:
        return not SeatSpec.parse(spec).human
    except ValueError:
        return False


def register_driver(spec: str, factory: DriverFactory, check: DriverCheck | None = None) -> None:
    if not is_driver_spec(spec):
        raise ValueError(f"driver {spec!r}: name it agent:<name>, or oracle:<name> where it cheats")
    _REGISTERED[spec] = DriverEntry(factory, check)


def _resolve(path: str | None) -> Any:
    if path is None:
        return None
    module, name = path.split(":")
    return getattr(importlib.import_module(module), name)


def _entry(spec: str) -> DriverEntry:
    if spec not in _REGISTERED and spec in BUILTIN:
        factory, check = BUILTIN[spec]
        _REGISTERED[spec] = DriverEntry(_resolve(factory), _resolve(check))
    if spec not in _REGISTERED:
        raise LookupError(f"unknown driver {spec!r}; known: {', '.join(driver_names())}")
    return _REGISTERED[spec]


def driver_names() -> list[str]:
    return sorted(set(BUILTIN) | set(_REGISTERED))


def available_drivers(parts: DriverParts) -> dict[str, str | None]:
    """Every driver by spec, with the reason it cannot start now, or None when it can."""
    result = {}
    for spec in driver_names():
        entry = _entry(spec)
        result[spec] = entry.check(parts) if entry.check is not None else None
    return result


def create_driver(spec: str, parts: DriverParts, seating: Seating) -> Agent:
    return _entry(spec).factory(parts, seating)

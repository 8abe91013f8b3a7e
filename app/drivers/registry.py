"""Agent Drivers by name: a trial's `driver` is `human` or `agent:<name>`.

A driver is a factory, `factory(info, services) -> DriverPolicy` (info: see `DriverPolicy.reset`;
services: settings, and the mazes with their cached graphs), and optionally a check,
`check(services) -> reason | None`, saying why it cannot start now (None: it can). The built-in
ones are named here by "module:function" and imported on first look-up, so the learned one
(`seq2seq`) imports torch only when it is checked or seated; `register_driver` adds more.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from app.drivers.base import DriverPolicy

if TYPE_CHECKING:
    from app.services import Services

DriverFactory = Callable[[dict[str, Any], "Services"], DriverPolicy]
DriverCheck = Callable[["Services"], "str | None"]

BUILTIN = {
    "random": ("app.drivers.baselines:random_driver", None),
    "shortest": ("app.drivers.baselines:shortest_driver", None),
    "seq2seq": ("app.drivers.seq2seq:seq2seq_driver", "app.drivers.seq2seq:seq2seq_check"),
}


@dataclass(frozen=True)
class DriverEntry:
    factory: DriverFactory
    check: DriverCheck | None = None


_REGISTERED: dict[str, DriverEntry] = {}


def register_driver(name: str, factory: DriverFactory, check: DriverCheck | None = None) -> None:
    _REGISTERED[name] = DriverEntry(factory, check)


def _resolve(path: str | None):
    if path is None:
        return None
    module, name = path.split(":")
    return getattr(importlib.import_module(module), name)


def _entry(name: str) -> DriverEntry:
    if name not in _REGISTERED and name in BUILTIN:
        factory, check = BUILTIN[name]
        _REGISTERED[name] = DriverEntry(_resolve(factory), _resolve(check))
    if name not in _REGISTERED:
        raise LookupError(f"unknown agent driver {name!r}; known: {', '.join(driver_names())}")
    return _REGISTERED[name]


def driver_names() -> list[str]:
    return sorted(set(BUILTIN) | set(_REGISTERED))


def available_drivers(services: Services) -> dict[str, str | None]:
    """Every agent Driver by name, with the reason it cannot start now, or None when it can."""
    result = {}
    for name in driver_names():
        entry = _entry(name)
        result[name] = entry.check(services) if entry.check is not None else None
    return result


def create_driver(name: str, info: dict[str, Any], services: Services) -> DriverPolicy:
    return _entry(name).factory(info, services)

"""Agent Drivers by name: a trial's `driver` is `human` or `agent:<name>`.

`register_driver(name, factory)`; the factory gets the trial info (see `DriverPolicy.reset`)
and the server's `Services` (settings, and the mazes with their cached graphs), and returns a `DriverPolicy`. Drivers register themselves on first
look-up; the learned one (`seq2seq`) imports torch only when a trial seats it, so the server
starts without it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from app.drivers.base import DriverPolicy
if TYPE_CHECKING:
    from app.services import Services

DriverFactory = Callable[[dict[str, Any], "Services"], DriverPolicy]

_FACTORIES: dict[str, DriverFactory] = {}


def register_driver(name: str, factory: DriverFactory) -> None:
    _FACTORIES[name] = factory


def _load_plugins() -> None:
    from app.drivers import baselines, seq2seq  # noqa: F401  (they register themselves)


def driver_names() -> list[str]:
    _load_plugins()
    return sorted(_FACTORIES)


def create_driver(name: str, info: dict[str, Any], services: "Services") -> DriverPolicy:
    _load_plugins()
    if name not in _FACTORIES:
        raise LookupError(f"unknown agent driver {name!r}; known: {', '.join(sorted(_FACTORIES))}")
    return _FACTORIES[name](info, services)

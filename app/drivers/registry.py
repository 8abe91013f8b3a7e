"""Agent Drivers by name: a trial's `driver` is `human` or `agent:<name>`.

`register_driver(name, factory)`; the factory gets the trial info (see `DriverPolicy.reset`)
and the `Settings`, and returns a `DriverPolicy`. The baselines are registered here; other
packages register theirs (e.g. `seq2seq`) by importing this module. Modules listed in
PLUGINS are imported on first look-up, so their agents appear without the server importing
torch at start.
"""

from __future__ import annotations

import importlib
import logging
from collections.abc import Callable
from typing import Any

from app.drivers.base import DriverPolicy
from app.settings import Settings

DriverFactory = Callable[[dict[str, Any], Settings], DriverPolicy]

_FACTORIES: dict[str, DriverFactory] = {}
PLUGINS = ("models.driver",)  # optional; absent until the learned Driver lands
logger = logging.getLogger(__name__)


def register_driver(name: str, factory: DriverFactory) -> None:
    _FACTORIES[name] = factory


def _load_plugins() -> None:
    from app.drivers import baselines  # noqa: F401  (registers random and shortest)

    for module in PLUGINS:
        try:
            importlib.import_module(module)
        except ModuleNotFoundError as err:
            if err.name is None or not module.startswith(err.name):
                logger.warning("driver plugin %s not loaded: %s", module, err)


def driver_names() -> list[str]:
    _load_plugins()
    return sorted(_FACTORIES)


def create_driver(name: str, info: dict[str, Any], settings: Settings) -> DriverPolicy:
    _load_plugins()
    if name not in _FACTORIES:
        raise LookupError(f"unknown agent driver {name!r}; known: {', '.join(sorted(_FACTORIES))}")
    return _FACTORIES[name](info, settings)

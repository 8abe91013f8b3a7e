"""Seat agents by spec: a trial's `driver` and `commander` are each `human`, `agent:<name>` or
`oracle:<name>`.

An agent is registered for a seat (`Role.DRIVER` or `Role.COMMANDER`); one name may name an agent
in each (`agent:dialog`). A factory is `factory(parts, seating) -> Agent`
(`sim.agents.turns.Agent`; parts: `AgentParts`, the settings and the mazes with their cached graphs; seating:
`app.seats.base.Seating`, whose `oracle` is set for `oracle:` drivers only and `maze` for
Commanders only), with optionally a check, `check(parts) -> reason | None`, saying why it
cannot start now (None: it can). The built-in ones are named here by "module:function" and
imported on first look-up, so the learned ones import torch only when they are checked or
seated; `register_agent` (`register_driver` for the Driver's seat) adds more.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from app.clock import ServerClock
from app.mazes import Mazes
from app.seats.base import Seating
from app.settings import Settings
from sim.trial.agent import Agent
from sim.trial.specs import HUMAN, SeatSpec
from sim.trial.vocabulary import Role


@dataclass(frozen=True)
class AgentParts:
    """What seat agents, their checks and their seats use of the server."""

    settings: Settings
    mazes: Mazes
    clock: ServerClock
    agent_checks: dict[Any, str | None] = field(default_factory=dict)  # agents' start checks, by file version


AgentFactory = Callable[[AgentParts, Seating], Agent]
AgentCheck = Callable[[AgentParts], "str | None"]

BUILTIN: dict[Role, dict[str, tuple[str, str | None]]] = {
    Role.DRIVER: {
        "agent:random": ("app.seats.baselines:random_driver", None),
        "agent:dialog": ("app.seats.dialog:dialog_driver", None),
        "agent:seq2seq": ("app.seats.seq2seq:seq2seq_driver", "app.seats.seq2seq:seq2seq_check"),
        "oracle:shortest": ("app.seats.baselines:shortest_driver", None),
    },
    Role.COMMANDER: {
        "agent:dialog": ("app.seats.dialog:dialog_commander", None),
    },
}


@dataclass(frozen=True)
class AgentEntry:
    factory: AgentFactory
    check: AgentCheck | None = None


_REGISTERED: dict[Role, dict[str, AgentEntry]] = {role: {} for role in BUILTIN}


def is_agent_spec(spec: str) -> bool:
    try:
        return not SeatSpec.parse(spec).human
    except ValueError:
        return False


def register_agent(role: Role, spec: str, factory: AgentFactory, check: AgentCheck | None = None) -> None:
    if not is_agent_spec(spec):
        raise ValueError(f"agent {spec!r}: name it agent:<name>, or oracle:<name> where it cheats")
    _REGISTERED[role][spec] = AgentEntry(factory, check)


def register_driver(spec: str, factory: AgentFactory, check: AgentCheck | None = None) -> None:
    register_agent(Role.DRIVER, spec, factory, check)


def _resolve(path: str | None) -> Any:
    if path is None:
        return None
    module, name = path.split(":")
    return getattr(importlib.import_module(module), name)


def _entry(role: Role, spec: str) -> AgentEntry:
    registered, builtin = _REGISTERED[role], BUILTIN[role]
    if spec not in registered and spec in builtin:
        factory, check = builtin[spec]
        registered[spec] = AgentEntry(_resolve(factory), _resolve(check))
    if spec not in registered:
        raise LookupError(f"unknown {role} {spec!r}; known: {', '.join(agent_names(role))}")
    return registered[spec]


def agent_names(role: Role) -> list[str]:
    return sorted(set(BUILTIN[role]) | set(_REGISTERED[role]))


def available_agents(parts: AgentParts, role: Role) -> dict[str, str | None]:
    """Every agent for the seat by spec, with the reason it cannot start now, or None when it can."""
    result = {}
    for spec in agent_names(role):
        entry = _entry(role, spec)
        result[spec] = entry.check(parts) if entry.check is not None else None
    return result


def available_drivers(parts: AgentParts) -> dict[str, str | None]:
    return available_agents(parts, Role.DRIVER)


def offered_agents(parts: AgentParts, role: Role, spec: str) -> dict[str, str | None] | None:
    """`available_agents` for a seat that `spec` gives an agent, else None (a person's: nothing to
    check). The checks load the learned agents' checkpoints (torch): seconds, at a server's first
    trial, that a trial of people does not need."""
    return None if spec == str(HUMAN) else available_agents(parts, role)


def available_seats(parts: AgentParts) -> dict[Role, dict[str, str | None]]:
    """`available_agents` for both seats: what `create_trial` checks a trial's seats against."""
    return {role: available_agents(parts, role) for role in (Role.COMMANDER, Role.DRIVER)}


def create_agent(role: Role, spec: str, parts: AgentParts, seating: Seating) -> Agent:
    return _entry(role, spec).factory(parts, seating)

"""`agent:dialog` in either seat. The Driver (`sim.agents.dialog_driver`) answers, waits for
instructions, follows them, reports and claims; the Commander (`sim.agents.dialog_commander`)
localizes the Driver from its words on the trial's map, guides it in words and judges its claims."""

from __future__ import annotations

from app.seats.base import Seating
from app.seats.registry import AgentParts
from sim.agents.dialog_commander import DialogCommander
from sim.agents.dialog_driver import DialogDriver


def dialog_driver(parts: AgentParts, seating: Seating) -> DialogDriver:
    return DialogDriver(seed=seating.seed, read_back=parts.settings.agent_read_back and seating.partner_human)


def dialog_commander(parts: AgentParts, seating: Seating) -> DialogCommander:
    assert seating.maze is not None  # a Commander's seat always has its map
    maze = parts.mazes.load(seating.maze)
    return DialogCommander(maze, seed=seating.seed, cache_dir=parts.settings.cache_dir)

"""An agent (or an oracle baseline) in the Driver's seat plays through the same protocol and log as a person."""

from __future__ import annotations

import asyncio

import pytest
from sqlalchemy import select

from app.db.models import Event
from app.seats.registry import agent_names, register_driver
from sim.agents.stepwise import StepwiseDriver
from sim.trial.vocabulary import Move, Role


@pytest.mark.trial(driver="oracle:shortest")
def test_shortest_path_oracle_drives_and_claims_each_target(server, trial):
    services = server.services

    async def command():
        async with trial.seat("commander") as commander:
            await commander.event("phase", phase="localizing")
            await commander.send("localize", x=1.0, y=1.0)
            for index in range(3):
                claimed = await commander.event("target_claimed", timeout=30, target_index=index)
                chat = await commander.event(
                    "chat", role="driver", start=0, text=f"I think I found the {claimed['payload']['target']}"
                )
                assert chat
                if index == 1:  # the agent keeps going after a rejection and claims again
                    start = len(commander.received)
                    await commander.send("reject")
                    await commander.event("target_claimed", timeout=30, start=start, target_index=1)
                await commander.send("confirm")
            await commander.event("phase", phase="finished", timeout=10)
            return commander

    commander = asyncio.run(command())
    assert "frame" not in commander.kinds()
    with services.db() as db:
        confirmed = db.scalars(
            select(Event.payload).where(Event.trial_id == trial.id, Event.kind == "target_confirmed")
        ).all()
        moves = db.scalars(select(Event.payload).where(Event.trial_id == trial.id, Event.kind == "move_executed")).all()
    assert all(c["truly_within"] for c in confirmed) and len(confirmed) == 3
    assert moves and all(m["outcome"] == "ok" for m in moves)


def test_register_driver_adds_a_named_agent(server, trials):
    class AlwaysLeft(StepwiseDriver):
        def decide(self):
            assert self.rays is not None and len(self.rays.labels) == 13  # it sees its frame's rays
            return Move.LEFT

    register_driver("agent:test-left", lambda services, seating: AlwaysLeft())
    assert {"agent:random", "agent:seq2seq", "agent:dialog", "oracle:shortest", "agent:test-left"} <= set(
        agent_names(Role.DRIVER)
    )
    services = server.services
    trial = trials.new(driver="agent:test-left")

    async def command():
        async with trial.seat("commander") as commander:
            await commander.event("phase", phase="localizing")
            await commander.send("localize", x=1.0, y=1.0)
            runtime = services.hub.peek(trial.id)
            for _ in range(500):
                if runtime.state.moves >= 3:
                    break
                await asyncio.sleep(0.02)

    asyncio.run(command())
    with services.db() as db:
        actions = db.scalars(
            select(Event.payload).where(Event.trial_id == trial.id, Event.kind == "move_executed")
        ).all()
    assert len(actions) >= 3 and {a["action"] for a in actions} == {"left"}


def test_an_agent_that_fails_is_logged_and_the_trial_pauses_saying_why(server, trials):
    def broken(services, seating):
        raise FileNotFoundError("no checkpoint at runs/missing.pt")

    register_driver("agent:test-broken", broken)
    services = server.services
    trial = trials.new(driver="agent:test-broken")

    async def command():
        async with trial.seat("commander") as commander:
            await commander.wait_for(lambda m: m.get("type") == "welcome")
            await asyncio.sleep(0.5)
            await commander.send("chat", text="anyone there?")
            await commander.event("chat", text="anyone there?")
            # The person is told: the trial pauses with the reason, not left talking to nothing.
            await commander.wait_for(lambda m: "agent stopped working" in str(m))

    asyncio.run(command())
    with services.db() as db:
        errors = db.scalars(select(Event.payload).where(Event.trial_id == trial.id, Event.kind == "bad_message")).all()
    assert errors == [{"role": "driver", "error": "agent 'agent:test-broken' failed: no checkpoint at runs/missing.pt"}]

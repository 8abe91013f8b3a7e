"""The learned NDH Driver (`agent:seq2seq`) plays the Driver's seat of a live trial, end to end:
a real checkpoint trained here, the real server, a scripted Commander over a websocket."""

from __future__ import annotations

import asyncio

import pytest
from sqlalchemy import func, select

from app.db.models import Event, Trial
from app.main import build_services
from app.seats.registry import available_drivers
from app.trial.setup import TrialSetupError
from bench.live import make_trial
from models.shipped import SHIPPED_CHECKPOINT, default_checkpoint
from models.train import load_agent
from tests.app.live import platform_settings


def events_of(services, trial_id: int, kind: str) -> list[Event]:
    with services.db() as db:
        return db.scalars(select(Event).where(Event.trial_id == trial_id, Event.kind == kind).order_by(Event.seq)).all()


@pytest.mark.slow
def test_learned_driver_claims_moves_after_a_rejection_and_claims_again(stopping_checkpoint, start_server, trials):
    server = start_server(seq2seq_checkpoint=stopping_checkpoint)
    services = server.services
    trial = trials.new(server, targets=("jar", "mug", "paddle"), driver="agent:seq2seq")

    async def command():
        async with trial.seat("commander") as commander:
            await commander.event("phase", phase="localizing", timeout=30)
            await commander.send("chat", text="find the jar, it is by the red wall")
            await commander.send("localize", x=1.0, y=1.0)
            await commander.event("target_claimed", timeout=30, target_index=0)
            await commander.event("chat", role="driver", text="I think I found the jar")
            start = len(commander.received)
            await commander.send("chat", text="no, keep looking")
            await commander.send("reject")
            rejected = await commander.event("target_rejected", start=start)
            again = await commander.event("target_claimed", timeout=30, start=start, target_index=0)
            start = len(commander.received)
            await commander.send("chat", text="yes, that is the jar. now the mug")
            await commander.send("confirm")
            # A new target re-encodes the dialog; the agent plays on and claims the mug.
            await commander.event("target_claimed", timeout=30, start=start, target_index=1)
            await commander.event("chat", role="driver", start=start, text="I think I found the mug")
            return rejected["seq"], again["seq"], again["payload"]["frame_id"]

    rejected_seq, again_seq, again_frame_id = asyncio.run(command())
    requested = [e for e in events_of(services, trial.id, "move_requested") if e.seq > rejected_seq]
    executed = [e for e in events_of(services, trial.id, "move_executed") if rejected_seq < e.seq < again_seq]
    frames = [e for e in events_of(services, trial.id, "frame") if e.seq > rejected_seq]
    assert requested and requested[0].payload["action"] in ("forward", "left", "right")
    assert executed and executed[0].payload["move_id"] == requested[0].payload["move_id"]
    assert executed[0].payload["outcome"] == "ok"
    assert frames, "the agent's move produced no camera frame"
    assert again_frame_id == frames[0].payload["frame_id"]  # it claimed again from where it moved to


def test_the_shipped_driver_loads_as_the_command_trained_it():
    agent, _, ckpt = load_agent(SHIPPED_CHECKPOINT)
    assert default_checkpoint() == SHIPPED_CHECKPOINT
    assert SHIPPED_CHECKPOINT.stat().st_size < 3_000_000  # package data: a few MB at most
    cfg = ckpt["train_config"]
    assert (cfg["model"], cfg["feedback"], cfg["blind"], cfg["seed"]) == ("improved", "student", "none", 0)
    assert agent.config.stop_head and agent.config.revisit_penalty == 1.0 and "optimizer" not in ckpt


@pytest.mark.slow
def test_without_a_setting_the_shipped_driver_plays_a_trial_on_a_bundled_maze(settings, server, trials):
    """A fresh install: no ROBOTSLANG_SEQ2SEQ_CHECKPOINT, so agent:seq2seq is the shipped Driver; it is
    offered, seated, and drives the simulated robot on one of the bundled generated mazes."""
    assert settings.seq2seq_checkpoint is None
    services = server.services
    assert available_drivers(services.agents)["agent:seq2seq"] is None
    maze = "gen-000"  # the first of the generated mazes shipped in sim/tasks/mazes/
    assert maze in services.mazes.names()
    trial = trials.new(maze=maze, targets=("jar", "mug", "paddle"), driver="agent:seq2seq")

    async def command():
        async with trial.seat("commander") as commander:
            await commander.event("phase", phase="localizing", timeout=30)
            await commander.send("chat", text="go forward and look for the jar by the wall")
            await commander.send("localize", x=1.0, y=1.0)
            for _ in range(1200):  # bounded wait for the Driver's first moves
                if len(events_of(services, trial.id, "move_executed")) >= 5:
                    break
                await asyncio.sleep(0.05)

    asyncio.run(command())
    executed = events_of(services, trial.id, "move_executed")
    requested = events_of(services, trial.id, "move_requested")
    assert len(executed) >= 5, "the shipped Driver made fewer than 5 moves"
    assert {e.payload["action"] for e in requested} <= {"forward", "left", "right", "stop"}
    assert {e.payload["move_id"] for e in executed} <= {e.payload["move_id"] for e in requested}


def test_seq2seq_that_cannot_start_is_not_offered_and_no_trial_is_created_for_it(tmp_path):
    """With a file that is not a checkpoint, or none at the set path, agent:seq2seq cannot start: it
    says why, and creating a trial with it fails with that reason (no trial for a Commander to wait in)."""
    broken = tmp_path / "broken.pt"
    broken.write_bytes(b"not a checkpoint at all")
    for checkpoint, why in ((broken, "cannot load checkpoint"), (tmp_path / "missing.pt", "missing.pt")):
        settings = platform_settings(tmp_path / f"var-{why[:8]}", seq2seq_checkpoint=checkpoint)
        services = build_services(settings)
        available = available_drivers(services.agents)
        assert available["agent:random"] is None and available["oracle:shortest"] is None
        assert why in available["agent:seq2seq"]
        with pytest.raises(TrialSetupError, match="cannot start") as refused:
            make_trial(services, services.mazes.names()[0], driver="agent:seq2seq")
        assert why in str(refused.value)
        with services.db() as db:
            assert db.scalar(select(func.count()).select_from(Trial)) == 0
        services.engine.dispose()


def test_a_loadable_checkpoint_is_offered(tmp_path, stopping_checkpoint):
    services = build_services(platform_settings(tmp_path, seq2seq_checkpoint=stopping_checkpoint))
    assert available_drivers(services.agents)["agent:seq2seq"] is None
    services.engine.dispose()

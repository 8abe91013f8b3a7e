"""Killing the server mid-trial loses no committed event, and the trial resumes from its log."""

from __future__ import annotations

import asyncio

import pytest

from sim.core.dynamics import Action, snap_pose, teacher_action
from sim.trial.state import fold
from tests.app.live import platform_settings
from tests.app.trial_play import claim_and_decide, move, start_trial


def logged_action(services, trial_id: int) -> Action:
    """Shortest-path move from the last pose in the log (the server is another process)."""
    state = fold(services.log.load(trial_id))
    graph, maze = services.mazes.graph(state.maze), services.mazes.load(state.maze)
    goal = graph.nearest_node(*maze.objects[state.current_target])
    return teacher_action(graph, snap_pose(graph, *state.pose), goal)


@pytest.mark.slow
def test_kill_and_restart_mid_trial_loses_no_committed_event(tmp_path, server_process, trials):
    server = server_process(platform_settings(tmp_path, cache_dir=tmp_path / "cache"))
    services = server.services
    trial = trials.new(server, targets=("jar", "paddle", "mug"))
    server.start()
    try:

        async def first_half():
            async with (
                trial.seat("commander") as commander,
                trial.seat("driver") as driver,
            ):
                await start_trial(commander, driver)
                await commander.send("localize", x=1.0, y=1.0)
                await driver.event("phase", phase="navigating")
                while (action := logged_action(services, trial.id)) != Action.STOP:
                    await move(driver, action.word)
                await claim_and_decide(commander, driver, confirm=True)
                for _ in range(3):
                    await move(driver, logged_action(services, trial.id).word)
                await commander.send("chat", text="keep going")
                await driver.event("chat", text="keep going")
                # Moves in flight while the server dies.
                for i in range(3):
                    await driver.send("move", action="left", move_id=f"dying{i}")
                server.kill()
                await asyncio.sleep(0.3)
                return commander.received + driver.received

        heard = asyncio.run(first_half())
        before = services.log.load(trial.id)
        committed = {e.seq: e for e in before}
        for message in heard:  # everything any seat heard of had been committed, as it was sent
            if message.get("type") == "event":
                event = committed[message["seq"]]
                assert event.kind == message["kind"]
                if message["kind"] == "chat":
                    assert event.payload == message["payload"]
        state_before = fold(before)
        assert state_before.phase == "navigating" and state_before.target_index == 1

        server.start()

        async def second_half():
            async with (
                trial.seat("commander") as commander,
                trial.seat("driver") as driver,
            ):
                welcome = await driver.wait_for(lambda m: m.get("type") == "welcome")
                assert welcome["phase"] == "navigating" and welcome["target_index"] == 1
                assert [h["payload"]["text"] for h in welcome["history"] if h["kind"] == "chat"] == ["keep going"]
                await commander.event("resumed", reason="disconnect:driver")
                for _ in range(2):
                    while (action := logged_action(services, trial.id)) != Action.STOP:
                        await move(driver, action.word)
                    await claim_and_decide(commander, driver, confirm=True)
                await commander.event("phase", phase="finished")

        asyncio.run(second_half())
    finally:
        server.stop()

    after = services.log.load(trial.id)
    assert after[: len(before)] == before, "no committed event lost or changed by the restart"
    assert [e.seq for e in after] == list(range(1, len(after) + 1))
    restart = after[len(before) :]
    assert {(e.kind, e.payload.get("role")) for e in restart[:4]} >= {
        ("disconnect", "commander"),
        ("disconnect", "driver"),
    }
    first_move = next(i for i, e in enumerate(restart) if e.kind == "move_executed")
    assert not any(e.kind == "pose" for e in restart[:first_move]), "the robot resumes where it was, not re-placed"
    final = fold(after)
    assert final.phase == "finished" and len(final.confirmed) == 3

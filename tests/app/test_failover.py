"""Several real server processes on PostgreSQL + Redis: `robotslang serve --workers 2` plays a
trial, and when the process that owns a trial is killed (SIGKILL, mid-trial) another takes it
over: nothing committed is lost, and both seats are served again."""

from __future__ import annotations

import asyncio
import os
import signal

import pytest
import redis
from sqlalchemy import select

from app.db.models import Event
from app.trial.relay import owner_key
from bench.live import SeatClient
from tests.app.live import platform_settings
from tests.app.trial_play import move, start_trial


def logged(services, trial_id: int) -> list[tuple[int, str, dict]]:
    with services.db() as db:
        rows = db.execute(
            select(Event.seq, Event.kind, Event.payload).where(Event.trial_id == trial_id).order_by(Event.seq)
        ).all()
    return [tuple(r) for r in rows]


def owner_pid(services, url: str, trial_id: int) -> int:
    """The pid of the process that owns the trial: the relay names each process by host and pid."""
    owner = redis.Redis.from_url(url, decode_responses=True).get(owner_key(services.settings, trial_id))
    assert owner is not None, "the trial has an owner"
    return int(owner.split("-")[-2])


async def chat_both_ways(commander: SeatClient, driver: SeatClient, tag: str) -> None:
    await commander.send("chat", text=f"commander {tag}")
    await driver.event("chat", text=f"commander {tag}", timeout=30)
    await driver.send("chat", text=f"driver {tag}")
    await commander.event("chat", text=f"driver {tag}", timeout=30)


@pytest.mark.slow
def test_two_workers_share_one_trial(tmp_path, postgres_url, redis_url, server_process, trials):  # noqa: F811
    settings = platform_settings(tmp_path, database_url=postgres_url, redis_url=redis_url)
    server = server_process(settings, workers=2)
    services = server.services
    trial = trials.new(server)
    server.start()
    try:

        async def play():
            async with (
                trial.seat("commander") as commander,
                trial.seat("driver") as driver,
            ):
                await start_trial(commander, driver)
                await chat_both_ways(commander, driver, "hello")
                await commander.send("localize", x=1.0, y=1.0)
                await driver.event("phase", phase="navigating")
                mark = len(driver.received)
                assert (await move(driver, "left"))["outcome"] == "ok"
                await driver.event("frame", start=mark)

        asyncio.run(play())
    finally:
        server.stop()
    kinds = [kind for _, kind, _ in logged(services, trial.id)]
    assert kinds.count("connect") == 2 and "move_executed" in kinds and "frame" in kinds
    seqs = [seq for seq, _, _ in logged(services, trial.id)]
    assert seqs == list(range(1, len(seqs) + 1)), "one total order, no gaps"


@pytest.mark.slow
def test_the_owner_killed_mid_trial_is_taken_over_and_its_seats_served_again(
    tmp_path, postgres_url, redis_url, server_process, trials
):
    """Two processes (two machines behind one proxy, as far as the trial can tell): the Commander
    on the first, which owns the trial, the Driver on the second. The first is killed; the second
    takes the trial over from the log and serves the Driver, and the Commander, reconnecting, is
    served there too."""
    settings = platform_settings(tmp_path, database_url=postgres_url, redis_url=redis_url)
    first, second = server_process(settings), server_process(settings)
    services = first.services
    trial = trials.new(first)
    first.start()
    second.start()
    try:

        async def play():
            commander = await trial.seat("commander").__aenter__()
            await commander.wait_for(lambda m: m.get("type") == "welcome")
            driver = await SeatClient(second.ws_url, trial.tokens["driver"]).__aenter__()
            await start_trial(commander, driver)
            await commander.send("localize", x=1.0, y=1.0)
            await driver.event("phase", phase="navigating")
            assert (await move(driver, "forward"))["outcome"] in ("ok", "collision")
            await chat_both_ways(commander, driver, "before")

            assert owner_pid(services, redis_url, trial.id) == first.proc.pid
            committed = logged(services, trial.id)
            os.kill(first.proc.pid, signal.SIGKILL)
            first.proc.wait(timeout=10)
            # The Driver's socket, on the surviving process, stays open: it is served again there.
            mark = len(driver.received)
            welcome = await driver.wait_for(lambda m: m.get("type") == "welcome", start=mark, timeout=30)
            assert welcome["phase"] == "navigating"
            # The Commander's socket died with its process: it reconnects to the survivor.
            await commander.__aexit__(None, None, None)
            async with SeatClient(second.ws_url, trial.tokens["commander"]) as commander:
                await commander.wait_for(lambda m: m.get("type") == "welcome")
                await chat_both_ways(commander, driver, "after")
                assert (await move(driver, "left"))["outcome"] == "ok"
            assert owner_pid(services, redis_url, trial.id) == second.proc.pid
            await driver.__aexit__(None, None, None)
            return committed

        committed = asyncio.run(play())
    finally:
        first.stop()
        second.stop()

    after = logged(services, trial.id)
    assert after[: len(committed)] == committed, "every event committed before the kill is still there, in order"
    later = [kind for _, kind, _ in after[len(committed) :]]
    assert "restarted" in later, "the new owner logs the takeover"
    chats = [p["text"] for _, kind, p in after if kind == "chat"]
    assert chats == ["commander before", "driver before", "commander after", "driver after"]
    assert [seq for seq, _, _ in after] == list(range(1, len(after) + 1))

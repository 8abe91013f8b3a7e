"""Two server processes share one trial through Redis pub/sub and PostgreSQL: the Commander
reaches one, the Driver the other, and the trial plays as if on one server."""

from __future__ import annotations

import asyncio

import pytest
from sqlalchemy import select

from app.db.models import Event, Experimenter, Trial
from app.security import hash_password
from bench.live import SeatClient
from tests.app.live import Watch, browser, experimenter_client, submit_login
from tests.app.trial_play import claim_and_decide, drive_to_target, move, start_trial


@pytest.mark.slow
def test_seats_on_two_processes_play_one_trial(cluster, trials):
    first, second = cluster
    trial = trials.new(first)
    experimenter = experimenter_client(second.services, second.url)

    async def play():
        async with trial.seat("commander") as commander:
            await commander.wait_for(lambda m: m.get("type") == "welcome")
            async with SeatClient(second.ws_url, trial.tokens["driver"]) as driver:
                await start_trial(commander, driver)
                owner = first.services.hub.peek(trial.id)
                assert owner is not None and second.services.hub.peek(trial.id) is None
                await driver.send("chat", text="hello from the other server")
                await commander.event("chat", text="hello from the other server")
                await commander.send("localize", x=1.0, y=1.0)
                await driver.event("phase", phase="navigating")
                # The experimenter's controls work from any process.
                pause = f"/experimenter/trials/{trial.id}/pause"
                await asyncio.to_thread(experimenter.post, pause, data={"reason": "a phone call"})
                await driver.event("paused", reason="experimenter", note="a phone call")
                await asyncio.to_thread(experimenter.post, f"/experimenter/trials/{trial.id}/resume")
                await commander.event("resumed", reason="experimenter")
                await driver.send("confirm")  # a bad message through the relay
                error = await driver.wait_for(lambda m: m.get("type") == "error")
                assert "may not send 'confirm'" in error["error"]
                assert (await move(driver, "left"))["outcome"] == "ok"
                for _ in range(3):
                    await drive_to_target(first.services, trial.id, driver)
                    await claim_and_decide(commander, driver, confirm=True)
                await driver.event("phase", phase="finished")
                return commander, driver

    commander, driver = asyncio.run(play())
    assert "frame" in driver.kinds() and "frame" not in commander.kinds()
    with first.services.db() as db:
        assert db.get(Trial, trial.id).phase == "finished"
        kinds = db.scalars(select(Event.kind).where(Event.trial_id == trial.id)).all()
    assert "bad_message" in kinds


def test_a_process_that_stops_hands_its_trials_to_another(cluster, trials):
    first, second = cluster
    trial = trials.new(first)

    async def before():
        async with (
            trial.seat("commander") as commander,
            trial.seat("driver") as driver,
        ):
            await start_trial(commander, driver)
            await commander.send("localize", x=1.0, y=1.0)
            await driver.event("phase", phase="navigating")
            assert (await move(driver, "right"))["outcome"] == "ok"

    asyncio.run(before())
    first.stop()

    async def after():  # the first process is gone; the second takes the trial over
        async with (
            SeatClient(second.ws_url, trial.tokens["commander"]) as commander,
            SeatClient(second.ws_url, trial.tokens["driver"]) as driver,
        ):
            welcome = await driver.wait_for(lambda m: m.get("type") == "welcome")
            assert welcome["phase"] == "navigating"
            assert second.services.hub.peek(trial.id) is not None
            assert (await move(driver, "left"))["outcome"] == "ok"
            await driver.send("chat", text="still here")
            await commander.event("chat", text="still here")

    asyncio.run(after())


@pytest.mark.slow
def test_a_watcher_on_another_process_sees_the_trials_particle_filter(cluster, trials):
    first, second = cluster
    trial = trials.new(first)
    with first.services.db.begin() as db:
        eve = Experimenter(name="eve", password_hash=hash_password("correct horse"))
        db.add(eve)
        db.flush()
        eve_id = eve.id
    cookie = second.services.sessions.issue(eve_id)

    async def play():
        async with (
            trial.seat("commander") as commander,
            trial.seat("driver") as driver,
        ):
            await start_trial(commander, driver)
            async with Watch(second, trial.id, cookie) as watch:
                # The filter is built when the first watcher comes (in the filters' share of a
                # core): a move made before it stands is not one it can count.
                await watch.wait_for(lambda m: m.get("type") == "belief", timeout=30)
                await commander.send("localize", x=1.0, y=1.0)
                await driver.event("phase", phase="navigating")
                assert (await move(driver, "left"))["outcome"] == "ok"
                seen = await watch.wait_for(lambda m: m.get("type") == "belief" and m["moves"] >= 1, timeout=30)
                assert seen["points"] and len(seen["mean"]) == 3
                assert first.services.hub.peek(trial.id) is not None and second.services.hub.peek(trial.id) is None

    asyncio.run(play())


@pytest.mark.settings(login_limit_per_account="3/minute")
def test_login_attempts_count_on_every_process(cluster):
    first, second = cluster
    with first.services.db.begin() as db:
        db.add(Experimenter(name="eve", password_hash=hash_password("correct horse")))
    assert [submit_login(browser(first.url), "eve", "guess").status_code for _ in range(3)] == [401] * 3
    limited = submit_login(browser(second.url), "eve", "correct horse")
    assert limited.status_code == 429 and "too many login attempts" in limited.text


def test_either_process_dashboard_lists_every_live_trial(cluster, trials):
    first, second = cluster
    trial = trials.new(first)
    experimenter = experimenter_client(second.services, second.url)

    def listed() -> dict[int, dict]:
        trials = experimenter.get("/experimenter/api/trials").json()["trials"]
        return {row["trial_id"]: row for row in trials}

    async def until_listed(moves: int) -> dict:
        for _ in range(100):  # each process publishes its trials once a second
            row = (await asyncio.to_thread(listed)).get(trial.id)
            if row is not None and row["moves"] == moves:
                return row
            await asyncio.sleep(0.1)
        raise AssertionError(f"trial {trial.id} with {moves} moves never listed by the other process")

    async def play():
        async with (
            trial.seat("commander") as commander,
            trial.seat("driver") as driver,
        ):
            await start_trial(commander, driver)
            assert second.services.hub.peek(trial.id) is None  # it runs in the first process alone
            await move(driver, "left")
            return await until_listed(moves=1)

    row = asyncio.run(play())
    assert row["phase"] == "localizing" and row["maze"] == first.services.mazes.names()[0]
    assert row["seats"] == {"commander": True, "driver": True}
    assert row["pose"] is not None  # the experimenter's view: the true pose, as on its own process
    first.stop()  # its trials leave the other process's dashboard with it
    assert trial.id not in listed()

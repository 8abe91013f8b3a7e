"""A seat that drops pauses the clock and tells the partner; it may rejoin within the grace
period, else the trial aborts. The experimenter pauses, resumes and aborts."""

from __future__ import annotations

import asyncio

import httpx
import pytest
from sqlalchemy import select

from app.db.models import Event
from tests.app.live import experimenter_client
from tests.app.trial_play import move, start_trial


def test_driver_drops_and_rejoins_within_grace(server, trial):
    services = server.services

    async def play():
        async with trial.seat("commander") as commander:
            async with trial.seat("driver") as driver:
                await start_trial(commander, driver)
            await commander.event("disconnect", role="driver")
            await commander.event("paused", reason="disconnect:driver")
            runtime = services.hub.peek(trial.id)
            frozen = runtime.state.active_s(services.clock.now_ns())
            await asyncio.sleep(0.4)
            assert runtime.state.active_s(services.clock.now_ns()) == frozen, "the clock stops while away"
            async with trial.seat("driver") as driver:
                welcome = await driver.wait_for(lambda m: m.get("type") == "welcome")
                assert welcome["phase"] == "localizing" and "frame" in welcome
                await commander.event("resumed", reason="disconnect:driver")
                executed = await move(driver, "right")
                assert executed["outcome"] == "ok"

    asyncio.run(play())


@pytest.mark.settings(grace_period_s=0.3)
def test_seat_gone_past_grace_aborts_the_trial(server, trial):
    services = server.services

    async def play():
        async with trial.seat("commander") as commander:
            async with trial.seat("driver") as driver:
                await start_trial(commander, driver)
            aborted = await commander.event("phase", phase="aborted", timeout=5)
            assert aborted["payload"]["reason"] == "the driver was away longer than the grace period"
            status = await commander.wait_for(lambda m: m.get("type") == "status" and m["phase"] == "aborted")
            assert status["abort_reason"] == aborted["payload"]["reason"]  # what the seat's page shows

    asyncio.run(play())
    with services.db() as db:
        kinds = db.scalars(select(Event.kind).where(Event.trial_id == trial.id).order_by(Event.seq)).all()
    # The camera's frames are their own stream: the start's frame may be logged after the
    # Driver left (its render finishes on a thread), so the control sequence is read without them.
    assert [k for k in kinds if k != "frame"][-3:] == ["disconnect", "paused", "phase"]


def test_experimenter_pauses_resumes_and_aborts(server, trial):
    experimenter = experimenter_client(server.services, server.url)

    async def play():
        async with (
            trial.seat("commander") as commander,
            trial.seat("driver") as driver,
        ):
            await start_trial(commander, driver)
            pause = f"/experimenter/trials/{trial.id}/pause"
            await asyncio.to_thread(experimenter.post, pause, data={"reason": " the fire alarm "})
            # The typed reason is logged with the pause and sent to the seats while it lasts.
            await driver.event("paused", reason="experimenter", note="the fire alarm")
            status = await commander.wait_for(lambda m: m.get("type") == "status" and m["paused"])
            assert status["pause_note"] == "the fire alarm"
            refused = await move(driver, "left")
            assert refused["outcome"] == "refused" and "paused" in refused["reason"]
            live = (await asyncio.to_thread(experimenter.get, "/experimenter/api/trials")).json()["trials"]
            assert live[0]["paused"] == ["experimenter"] and live[0]["pose"] is not None
            assert live[0]["pause_note"] == "the fire alarm"
            seen = len(commander.received)
            await asyncio.to_thread(experimenter.post, f"/experimenter/trials/{trial.id}/resume")
            await driver.event("resumed", reason="experimenter")
            status = await commander.wait_for(lambda m: m.get("type") == "status" and not m["paused"], start=seen)
            assert status["pause_note"] is None
            assert (await move(driver, "left"))["outcome"] == "ok"
            await asyncio.to_thread(
                experimenter.post,
                f"/experimenter/trials/{trial.id}/abort",
                data={"reason": "the room's network went down"},
            )
            aborted = await commander.event("phase", phase="aborted")
            assert aborted["payload"]["reason"] == "stopped by the experimenter: the room's network went down"
            await driver.send("chat", text="hello?")
            error = await driver.wait_for(lambda m: m.get("type") == "error")
            assert "aborted" in error["error"]

    asyncio.run(play())
    # Anonymous visitors cannot control trials.
    anonymous = httpx.post(f"{server.url}/experimenter/trials/{trial.id}/resume")
    assert anonymous.status_code == 303 and anonymous.headers["location"] == "/"

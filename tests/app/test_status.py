"""Every seat is told where the trial stands (`status`), and the experimenter can watch it live:
the Driver's camera and the true pose, which no participant's view changes for."""

from __future__ import annotations

import asyncio
import math

import pytest
import websockets

from app.db.models import Event, Experimenter
from app.security import hash_password
from tests.app.live import Watch
from tests.app.trial_play import claim_and_decide, drive_to_target, move, start_trial

FIELDS = {
    "type",
    "phase",
    "target_index",
    "targets_total",
    "elapsed_s",
    "running",
    "moves",
    "paused",
    "waiting_for",
    "claim_pending",
    "abort_reason",
    "pause_note",
    "join_left_s",
}


def statuses(client) -> list[dict]:
    return [m for m in client.received if m.get("type") == "status"]


def test_seats_get_the_status_and_the_experimenter_watches_the_driver(server, trial):
    services = server.services
    with services.db.begin() as db:
        eve = Experimenter(name="eve", password_hash=hash_password("correct horse"))
        db.add(eve)
        db.flush()
        eve_id = eve.id
    cookie = services.sessions.issue(eve_id)  # once eve is committed: the session reads her version

    async def play():
        async with trial.seat("commander") as commander:
            welcome = await commander.wait_for(lambda m: m.get("type") == "welcome")
            assert set(welcome["status"]) == FIELDS
            assert welcome["status"]["phase"] == "waiting" and welcome["status"]["waiting_for"] == ["driver"]
            assert welcome["status"]["join_left_s"] is None, "no join deadline outside a study's lobby"
            async with (
                Watch(server, trial.id, cookie) as watch,
                trial.seat("driver") as driver,
            ):
                await start_trial(commander, driver)
                started = await commander.wait_for(lambda m: m.get("type") == "status" and m["running"])
                assert started["phase"] == "localizing" and started["targets_total"] == 3
                assert started["waiting_for"] == [] and started["moves"] == 0
                await move(driver, "left")
                await move(driver, "right")
                moved = await commander.wait_for(lambda m: m.get("type") == "status" and m["moves"] == 2)
                assert moved["elapsed_s"] >= started["elapsed_s"]
                await watch.wait_for(lambda m: m.get("type") == "status" and m["moves"] == 2)
                frame = await watch.wait_for(lambda m: m.get("kind") == "frame" and "jpeg" in m)
                pose = await watch.event("pose")
                assert set(pose["payload"]) >= {"x", "y", "heading"}
                watch_welcome = watch.received[0]
                assert watch_welcome["type"] == "welcome" and set(watch_welcome["status"]) == FIELDS
                assert frame["payload"]["frame_id"] > 0
                start = len(commander.received)
                await commander.send("chat", text="stop a moment")
                await commander.event("chat", start=start)
                # A chat changes no status field: no status message for it.
                assert all(m.get("type") != "status" for m in commander.received[start:])
            return commander, driver

    commander, driver = asyncio.run(play())
    assert not commander.kinds() & {"frame", "move_executed", "move_requested", "pose"}
    assert "pose" not in driver.kinds() and "localization" not in driver.kinds()
    assert all(set(m) == FIELDS for m in statuses(driver))


def test_the_watch_socket_needs_the_experimenter_login(server, trial):
    async def attempt(cookie):
        async with Watch(server, trial.id, cookie):
            pass

    for cookie in (None, "forged"):
        with pytest.raises(websockets.InvalidStatus) as refused:
            asyncio.run(attempt(cookie))
        assert refused.value.response.status_code == 403


def test_a_pending_claim_is_in_the_status_until_the_commander_decides(server, trial):
    services = server.services

    async def play():
        async with (
            trial.seat("commander") as commander,
            trial.seat("driver") as driver,
        ):
            await start_trial(commander, driver)
            await commander.send("localize", x=1.2, y=1.0, heading=0.5)
            await driver.event("phase", phase="navigating", target_index=0)
            await drive_to_target(services, trial.id, driver)
            start = len(driver.received)
            await claim_and_decide(commander, driver, confirm=False)
            await driver.wait_for(lambda m: m.get("type") == "status" and not m["claim_pending"], start=start)
            return [m["claim_pending"] for m in statuses(driver)[-2:]]

    assert asyncio.run(play()) == [True, False], "the claim shows as pending, then as decided"
    # Poses are recorded with headings in (-pi, pi] (to the event's 1 mrad), as the rover's tracker gives them.
    with services.db() as db:
        headings = {round(e.payload["heading"], 3) for e in db.query(Event).filter_by(trial_id=trial.id, kind="pose")}
    assert len(headings) > 2 and all(-math.pi < h <= round(math.pi, 3) for h in headings), headings

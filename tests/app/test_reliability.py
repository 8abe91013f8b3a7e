"""What holds when the server dies, a seat is gone, a message comes twice or a rover reconnects:
real SQLite files, real server processes and threads, real websockets over loopback."""

from __future__ import annotations

import asyncio
import contextlib
import json
import time

import pytest
import websockets
from sqlalchemy import select

from app.db.models import Trial
from app.routes.seat_ws import TRIAL_OVER
from sim.trial.state import fold
from tests.app.live import experimenter_client, session_cookie
from tests.app.trial_play import move, start_trial
from tests.app.wire_rover import Rover, rover_trial

S = 1_000_000_000


def until(predicate, what: str, timeout: float = 20.0):
    """Poll a condition on the database (the server may be another process)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.05)
    raise AssertionError(f"{what}: not within {timeout} s")


@pytest.mark.slow
def test_a_crash_neither_scores_the_downtime_nor_leaves_a_move_requested(server_process, trials):
    server = server_process()
    services = server.services
    trial_id, rover_token = rover_trial(services)
    trial = trials.of(trial_id, on=server)
    server.start()
    try:

        async def until_crash():
            async with (
                Rover(server.ws_url, rover_token) as rover,
                trial.seat("commander") as commander,
                trial.seat("driver") as driver,
            ):
                await start_trial(commander, driver)
                await driver.send("move", action="forward", move_id="held")
                while not rover.moves:  # the rover got it, and will never acknowledge it
                    await asyncio.sleep(0.02)
                server.kill()

        asyncio.run(until_crash())
        before = services.log.load(trial_id)
        assert before[-1].kind == "move_requested" and before[-1].payload["move_id"] == "held"
        time.sleep(1.5)  # the server is down; this must not count on the trial clock
        server.start()  # reopens its running trials at start
        after = until(
            lambda: [e for e in services.log.load(trial_id) if e.seq > before[-1].seq], "the reopened trial's events"
        )
    finally:
        server.stop()
    done = [e for e in after if e.kind == "move_executed" and e.payload["move_id"] == "held"]
    assert [(e.payload["outcome"], e.payload["reason"]) for e in done] == [("refused", "server restart")]
    assert fold(before + after).active_ns == fold(before).active_ns, "the clock stopped at the last event"
    assert fold(before + after).moves_in_flight == {}


@pytest.mark.settings(grace_period_s=4.0)
@pytest.mark.slow
def test_a_seat_that_dropped_before_a_crash_still_times_out(settings, server_process, trials):
    grace_s = settings.grace_period_s
    server = server_process()
    services = server.services
    trial = trials.new(server)
    server.start()
    try:

        async def until_crash():
            async with trial.seat("commander") as commander:
                async with trial.seat("driver") as driver:
                    await start_trial(commander, driver)
                await commander.event("paused", reason="disconnect:driver")
                await asyncio.sleep(1.0)
                await commander.send("chat", text="where did you go?")  # the last event before the crash
                await commander.event("chat", text="where did you go?")
                server.kill()

        asyncio.run(until_crash())
        before = services.log.load(trial.id)
        server.start()  # nobody comes back
        until(lambda: fold(services.log.load(trial.id)).over, "the grace timer's abort", timeout=30)
    finally:
        server.stop()
    log = services.log.load(trial.id)
    dropped = next(e for e in before if e.kind == "disconnect" and e.payload["role"] == "driver")
    reopened = next(e for e in log if e.kind == "restarted")
    aborted = log[-1]
    assert aborted.kind == "phase" and aborted.payload["phase"] == "aborted"
    assert not any(e.kind == "connect" for e in log if e.seq > before[-1].seq)
    # The time that remained at the crash ran after the restart (a timer never fires early).
    remaining_ns = grace_s * S - (before[-1].t_ns - dropped.t_ns)
    assert aborted.t_ns - reopened.t_ns >= remaining_ns
    with services.db() as db:
        assert db.get(Trial, trial.id).phase == "aborted"


@pytest.mark.settings(grace_period_s=0.3)
def test_a_trial_ended_by_its_grace_timer_leaves_the_live_list_and_reopens_without_a_new_event(server, trial):
    services = server.services

    async def play():
        async with (
            trial.seat("commander") as commander,
            trial.seat("driver") as driver,
        ):
            await start_trial(commander, driver)
        # Both gone: the first grace timer to run out aborts the trial.
        until(lambda: services.hub.peek(trial.id) is None, "the ended trial to leave this process")
        assert services.hub.live() == []
        ended = services.log.load(trial.id)
        away = {f"the {role} was away longer than the grace period" for role in ("commander", "driver")}
        assert ended[-1].payload["phase"] == "aborted" and ended[-1].payload["reason"] in away
        # The seat's join link closed with the trial: its socket is closed at once with the code
        # the seat page reloads on, and why (a bare 403 left the page reconnecting forever).
        async with websockets.connect(f"{server.ws_url}?token={trial.tokens['commander']}") as seat:
            with pytest.raises(websockets.exceptions.ConnectionClosed) as closed:
                await asyncio.wait_for(seat.recv(), 5)
        assert closed.value.rcvd.code == TRIAL_OVER
        assert closed.value.rcvd.reason == "this trial was stopped: ask the experimenter what comes next"
        assert services.hub.peek(trial.id) is None, "the closed link opened nothing"
        # The experimenter's watch reopens it.
        cookie = session_cookie(await asyncio.to_thread(experimenter_client, services, server.url))
        async with websockets.connect(
            f"ws://127.0.0.1:{server.port}/ws/watch/{trial.id}", additional_headers={"Cookie": cookie}
        ) as watch:
            welcome = json.loads(await watch.recv())
            assert welcome["type"] == "welcome" and welcome["phase"] == "aborted"
            assert welcome["status"]["running"] is False
        assert services.log.load(trial.id) == ended, "reopening an ended trial appends nothing"

    asyncio.run(play())


def test_a_move_id_sent_twice_executes_once(server, trial):
    services = server.services

    async def play():
        async with (
            trial.seat("commander") as commander,
            trial.seat("driver") as driver,
        ):
            await start_trial(commander, driver)
            await driver.send("move", action="left", move_id="once")
            first = await driver.event("move_executed", move_id="once")
            assert first["payload"]["outcome"] == "ok"
            start = len(driver.received)
            await driver.send("move", action="left", move_id="once")
            error = await driver.wait_for(lambda m: m.get("type") == "error", start=start)
            assert "'once' was already received" in error["error"]
            await move(driver, "right")  # the next move is executed as usual

    asyncio.run(play())
    log = services.log.load(trial.id)
    assert [e.kind for e in log if e.payload.get("move_id") == "once"] == ["move_requested", "move_executed"]
    assert fold(log).moves == 2


def test_frame_stamps_stay_monotonic_across_a_rover_reconnection(server, trials):
    services = server.services
    trial_id, rover_token = rover_trial(services)
    trial = trials.of(trial_id)

    async def play():
        async with (
            trial.seat("commander") as commander,
            trial.seat("driver") as driver,
        ):
            async with Rover(server.ws_url, rover_token) as rover:
                await start_trial(commander, driver)
                while rover.pongs < 3:  # the server knows the rover's clock
                    await asyncio.sleep(0.02)
                await rover.frame(1, rover.now())
                first = await driver.event("frame")
            # The rover comes back; the first frame it sends was captured before the link dropped.
            async with Rover(server.ws_url, rover_token) as rover:
                while rover.pongs < 3:
                    await asyncio.sleep(0.02)
                start = len(driver.received)
                await rover.frame(2, rover.now() - 2 * S)
                second = await driver.event("frame", start=start)
                start = len(driver.received)
                await rover.frame(3, rover.now())
                third = await driver.event("frame", start=start)
            return [m["payload"]["capture_ns"] for m in (first, second, third)]

    stamps = asyncio.run(play())
    assert stamps[0] < stamps[1] < stamps[2]
    assert len({e.payload["path"] for e in services.log.load(trial_id) if e.kind == "frame"}) == 3


def test_a_message_over_the_transport_limit_gets_the_error_reply_and_is_logged(server, trial):
    services = server.services
    with server.services.db() as db:
        assert db.scalar(select(Trial.phase).where(Trial.id == trial.id)) == "waiting"

    async def play():
        async with trial.seat("driver") as driver:
            await driver.wait_for(lambda m: m.get("type") == "welcome")
            with contextlib.suppress(websockets.ConnectionClosed):
                await driver.send("chat", text="x" * (8 * 1024 * 1024))
            error = await driver.wait_for(lambda m: m.get("type") == "error")
            await asyncio.wait_for(driver._reader, 10)  # then the server closes the socket
            return error, driver.ws.close_code

    error, code = asyncio.run(play())
    assert error["code"] == "bad_message" and "over the limit" in error["error"]
    assert code == 1009
    bad = until(lambda: [e for e in services.log.load(trial.id) if e.kind == "bad_message"], "the log entry")
    assert bad[0].payload["role"] == "driver" and "over the limit" in bad[0].payload["error"]

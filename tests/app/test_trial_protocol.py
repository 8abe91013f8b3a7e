"""A whole trial through real websockets on loopback, against a real database file (and
PostgreSQL): chat, moves and frames, localization, claims confirmed and rejected, the
leaderboard; and what each seat is never sent."""

from __future__ import annotations

import asyncio
import time

import httpx
import pytest
from sqlalchemy import select

from app.db.models import Event, Frame, Trial
from tests.app.trial_play import claim_and_decide, drive_to_target, move, start_trial


def first_maze(services) -> str:
    return services.mazes.names()[0]


async def logged_runs(services, trial_id: int, requests: int) -> list[dict]:
    """The trial's `moves_refused` events once they count `requests` (a run is logged when it
    ends, at the latest `REFUSED_RUN_S` after its first request)."""
    for _ in range(60):
        with services.db() as db:
            runs = [
                e.payload
                for e in db.scalars(select(Event).where(Event.trial_id == trial_id, Event.kind == "moves_refused"))
            ]
        if sum(r["count"] for r in runs) >= requests:
            assert sum(r["count"] for r in runs) == requests, runs
            return runs
        await asyncio.sleep(0.1)
    raise AssertionError(f"the log counts {sum(r['count'] for r in runs)} refused requests, not {requests}")


def test_full_trial_from_links_to_leaderboard(any_db_settings, start_server, trials):
    server = start_server(any_db_settings)
    services = server.services
    trial = trials.new(server, first_maze(services), targets=("paddle", "mug", "jar"), team="Owls")

    async def play():
        async with (
            trial.seat("commander") as commander,
            trial.seat("driver") as driver,
        ):
            await start_trial(commander, driver)
            # Chat goes both ways; the first frame reaches the Driver.
            await commander.send("chat", text="I see a blue wall on my map. What do you see?")
            await driver.event("chat", role="commander")
            await driver.send("chat", text="A red wall straight ahead.")
            await commander.event("chat", role="driver")
            # The Driver sees the camera from the start: in the welcome, or right after it.
            welcome = await driver.wait_for(lambda m: m.get("type") == "welcome")
            first = welcome["frame"] if "frame" in welcome else await driver.event("frame")
            assert first["jpeg"]
            executed = await driver.event("move_executed", move_id=(await move(driver, "left"))["move_id"])
            await driver.event("frame", start=driver.received.index(executed))
            # The Commander's first mark ends localization.
            await commander.send("localize", x=1.2, y=1.0, heading=0.5)
            await driver.event("phase", phase="navigating", target_index=0)
            for index in range(3):
                await drive_to_target(services, trial.id, driver)
                if index == 0:  # a wrong call first: rejected, and the trial goes on
                    await claim_and_decide(commander, driver, confirm=False)
                claimed = await claim_and_decide(commander, driver, confirm=True)
                assert claimed["claim"]["jpeg"], "the Commander sees the Driver's frame at a claim"
            await commander.event("phase", phase="finished")
            return commander, driver

    commander, driver = asyncio.run(play())
    deadline = time.time() + 5
    while services.hub.peek(trial.id) is not None:  # over, and both seats gone
        assert time.time() < deadline, "a finished trial with no seats stays in the hub"
        time.sleep(0.05)

    # The Commander never got a camera frame, a move or the true pose; the Driver never
    # the Commander's localization; neither the simulator's ground truth.
    assert not commander.kinds() & {"frame", "pose", "move_executed", "move_requested"}
    assert not any("frame" in m for m in commander.received if m.get("type") == "welcome")
    assert not driver.kinds() & {"pose", "localization", "move_requested"}
    for m in commander.received + driver.received:
        if m.get("kind") in ("target_confirmed", "target_rejected"):
            assert "within_m" not in m["payload"] and "truly_within" not in m["payload"]
    assert driver.kinds() >= {"frame", "move_executed", "chat", "target_confirmed"}

    with services.db() as db:
        events = db.scalars(select(Event).where(Event.trial_id == trial.id).order_by(Event.seq)).all()
        frames = db.scalars(select(Frame).where(Frame.trial_id == trial.id)).all()
        row = db.get(Trial, trial.id)
    assert [e.seq for e in events] == list(range(1, len(events) + 1))
    assert all(a.t_ns < b.t_ns for a, b in zip(events, events[1:])), "one clock, strictly increasing per trial"
    confirmed = [e.payload for e in events if e.kind == "target_confirmed"]
    assert [c["target"] for c in confirmed] == ["paddle", "mug", "jar"]
    assert all(c["truly_within"] and c["within_m"] <= 0.508 for c in confirmed)
    assert [e.payload["target"] for e in events if e.kind == "target_rejected"] == ["paddle"]
    frame_events = [e for e in events if e.kind == "frame"]
    assert len(frames) == len(frame_events) > 3
    for f in frames:
        assert (any_db_settings.frames_dir / f.path).read_bytes()[:2] == b"\xff\xd8"  # a JPEG on disk
    assert row.phase == "finished" and row.moves == sum(
        1 for e in events if e.kind == "move_executed" and e.payload["outcome"] != "refused"
    )

    page = httpx.get(server.url + "/leaderboard").text
    assert "Owls" in page
    expected = row.active_s + any_db_settings.move_penalty_s * row.moves
    assert f"{expected:.1f}" in page


def test_seat_pages_show_only_their_own_view(server, trial):
    commander, driver = trial.tokens["commander"], trial.tokens["driver"]
    assert httpx.get(f"{server.url}/play/{commander}/map.png").headers["content-type"] == "image/png"
    assert httpx.get(f"{server.url}/play/{driver}/map.png").status_code == 403
    assert httpx.get(f"{server.url}/play/{driver}/target/0.jpg").status_code == 403
    assert httpx.get(f"{server.url}/play/{commander}/target/0.jpg").content[:2] == b"\xff\xd8"
    assert httpx.get(f"{server.url}/play/{commander}/target/2.jpg").status_code == 404, "not a later target"
    page = httpx.get(f"{server.url}/play/{driver}").text
    assert 'id="camera"' in page and "map.png" not in page
    page = httpx.get(f"{server.url}/play/{commander}").text
    assert 'id="map"' in page and 'id="camera"' not in page
    assert httpx.get(f"{server.url}/play/{driver[:-3]}xyz").status_code == 403
    # A pasted join link on the home page leads to the seat; anything else is named as invalid.
    joined = httpx.get(f"{server.url}/join", params={"link": f"{server.url}/play/{driver}"})
    assert joined.status_code == 303 and joined.headers["location"] == f"/play/{driver}"
    assert "not a valid join link" in httpx.get(f"{server.url}/join", params={"link": "http://x/play/abc"}).text


@pytest.mark.parametrize("who", ["forged", "other trial"])
def test_forged_or_foreign_token_is_refused_at_connect(who, server, trial, trials):
    import websockets

    if who == "forged":
        from app.security import SeatTokens

        token = SeatTokens("not-the-server-key").issue(trial.id, "driver")
    else:
        token = trials.of(trial.id + 999).tokens["driver"]

    async def connect():
        async with websockets.connect(f"{server.ws_url}?token={token}") as ws:
            await ws.recv()

    with pytest.raises(websockets.InvalidStatus) as err:
        asyncio.run(connect())
    assert err.value.response.status_code == 403


def test_other_role_token_and_bad_messages_get_errors_and_never_end_the_trial(server, trial):
    services = server.services

    async def play():
        async with (
            trial.seat("commander") as commander,
            trial.seat("driver") as driver,
        ):
            await start_trial(commander, driver)

            async def refused(client, type_, expect: str, raw=None, **fields):
                start = len(client.received)
                if raw is not None:
                    await client.ws.send(raw)
                else:
                    await client.send(type_, **fields)
                error = await client.wait_for(lambda m: m.get("type") == "error", start=start)
                assert expect in error["error"], error

            # The Driver's own link cannot act as the Commander, nor the Commander move.
            await refused(driver, "confirm", "may not send 'confirm'")
            await refused(commander, "move", "may not send 'move'", action="forward")
            # A Commander's socket carrying the Driver's token is refused on the message.
            await refused(commander, "chat", "token refused", token=trial.tokens["driver"], text="hi")
            await refused(driver, "chat", "token refused", token=trial.tokens["driver"][:-2] + "xx", text="hi")
            await refused(driver, None, "invalid message", raw="not json at all")
            await refused(driver, None, "JSON text", raw=b"\x00\x01")
            await refused(driver, "teleport", "invalid message")
            await refused(driver, "move", "action", action="jump")
            await refused(driver, "chat", "text", text="x" * 501)
            await refused(driver, "chat", "limit is", text="y" * 480, padding="z" * 5000)
            await refused(commander, "localize", "x", x=9.0, y=1.0)
            # Wrong types are refused, never coerced.
            await refused(commander, "localize", "valid number", x="0.5", y=1.0)
            await refused(commander, "localize", "valid number", x=1.0, y=True)
            await refused(commander, "confirm", "no claimed target")
            await refused(driver, "claim", "once the Commander has marked the robot")
            # The trial goes on.
            await driver.send("chat", text="still here")
            await commander.event("chat", text="still here")

    asyncio.run(play())
    with services.db() as db:
        bad = db.scalars(select(Event).where(Event.trial_id == trial.id, Event.kind == "bad_message")).all()
        phase = db.get(Trial, trial.id).phase
    assert len(bad) == 15 and {b.payload["role"] for b in bad} == {"commander", "driver"}
    assert phase == "localizing"


@pytest.mark.settings(min_move_interval_s=2.0)
def test_moves_faster_than_the_robot_are_refused_not_queued(server, trial):
    async def play():
        async with (
            trial.seat("commander") as commander,
            trial.seat("driver") as driver,
        ):
            await start_trial(commander, driver)
            for i in range(5):  # a burst, as from a held-down key
                await driver.send("move", action="left", move_id=f"burst{i}")
            outcomes = [await driver.moved(f"burst{i}") for i in range(5)]
            await asyncio.sleep(0.8)  # anything queued would have executed by now
            return [o["outcome"] for o in outcomes], driver

    outcomes, driver = asyncio.run(play())
    assert outcomes[0] == "ok" and outcomes[1:] == ["refused"] * 4
    executed = [m for m in driver.received if m.get("kind") == "move_executed"]
    assert len(executed) == 1
    refusals = [m for m in driver.received if m.get("type") == "move_refused"]
    assert [m["move_id"] for m in refusals] == [f"burst{i}" for i in range(1, 5)]
    assert {m["reason"] for m in refusals} <= {
        "the previous move is still executing",
        "too soon after the previous move",
    }
    runs = asyncio.run(logged_runs(server.services, trial.id, requests=4))
    assert len(runs) <= 2  # one event a run of refusals (a reason each), not one a request


@pytest.mark.settings(allowed_origins=["https://lab.example"])
def test_websocket_from_another_origin_is_refused(server, trial):
    import websockets

    async def connect(origin):
        async with trial.seat("commander", origin=origin) as seat:
            return await seat.wait_for(lambda m: m.get("type") == "welcome")

    with pytest.raises(websockets.InvalidStatus):
        asyncio.run(connect("http://evil.example"))
    assert asyncio.run(connect(server.url))["role"] == "commander"
    assert asyncio.run(connect("https://lab.example"))["role"] == "commander"

"""The rover end to end on loopback: the real server (uvicorn), the real `robotslang-robot`
process (mock motors logging their pins, synthetic camera), seats over real websockets."""

from __future__ import annotations

import asyncio
import json
import re
import time

import cv2
import httpx
import numpy as np
import pytest
import websockets
from sqlalchemy import select

from app.db.models import Frame as FrameRow
from app.rover.links import MAX_FRAME_BYTES
from bench.live import SeatClient
from robot_client.calibration import Calibration
from robot_client.protocol import pack_frame
from tests.app.live import page_csrf_token
from tests.app.robot_rig import (
    ROBOT_START_S,
    WATCHDOG_S,
    RobotProcess,
    new_robot_trial,
    robot_status,
    trial_events,
)

pytestmark = pytest.mark.anyio
TINY_JPEG = cv2.imencode(".jpg", np.zeros((8, 8, 3), np.uint8))[1].tobytes()


@pytest.fixture(scope="module")
def server(start_module_server):
    return start_module_server(min_move_interval_s=0.0)


@pytest.fixture
def robots(tmp_path):
    started: list[RobotProcess] = []

    def start(*args, **kwargs) -> RobotProcess:
        robot = RobotProcess(tmp_path, *args, **kwargs)
        started.append(robot)
        return robot

    yield start
    for robot in started:
        print(robot.stop())


async def until(predicate, timeout: float = 15.0, what: str = "condition"):
    """The first true value of `predicate()` (awaited when it is a coroutine), polled until `timeout`."""
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if asyncio.iscoroutine(value):
            value = await value
        if value:
            return value
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        await asyncio.sleep(0.02)


def pulses(log: list[dict]) -> list[tuple[str, float, int]]:
    """(pin, seconds on, start t_ns) for every pulse in a pin log, in start order."""
    on: dict[str, int] = {}
    found = []
    for e in log:
        if e["state"] > 0:
            on[e["pin"]] = e["t_ns"]
        elif e["pin"] in on:
            start = on.pop(e["pin"])
            found.append((e["pin"], (e["t_ns"] - start) / 1e9, start))
    return sorted(found, key=lambda p: p[2])


def frame_events(seat: SeatClient) -> list[dict]:
    return [m for m in seat.received if m.get("type") == "event" and m["kind"] == "frame"]


async def test_frames_reach_the_driver_and_the_log_with_monotonic_times(server, robots):
    robot_id, token, trial = new_robot_trial(server, "frames")
    robots(server.url, token)
    async with trial.seat("commander") as commander, trial.seat("driver") as driver:
        await driver.event("phase", phase="localizing", timeout=ROBOT_START_S)
        await until(lambda: len(frame_events(driver)) >= 12, timeout=ROBOT_START_S, what="12 frames at the Driver")
    frames = frame_events(driver)
    capture = [f["payload"]["capture_ns"] for f in frames]
    stamped = [f["t_ns"] for f in frames]
    assert all(b > a for a, b in zip(capture, capture[1:]))
    assert all(b > a for a, b in zip(stamped, stamped[1:]))
    assert all(c <= t for c, t in zip(capture, stamped))  # captured before it was logged
    assert all(f["jpeg"][:4] == "/9j/" for f in frames)  # base64 of a JPEG's FF D8 FF
    assert all(f["payload"]["source"] == "driver" and f["payload"]["width"] == 320 for f in frames)
    assert not any(m.get("kind") == "frame" for m in commander.received)

    logged = trial_events(server, trial, "frame")
    ids = {f["payload"]["frame_id"] for f in frames}
    assert ids <= {e.seq for e in logged}
    with server.services.db() as db:
        rows = db.scalars(select(FrameRow).where(FrameRow.trial_id == trial.id).order_by(FrameRow.seq)).all()
    assert [r.capture_ns for r in rows] == sorted(r.capture_ns for r in rows)
    assert (server.services.settings.frames_dir / rows[0].path).read_bytes()[:2] == b"\xff\xd8"
    status = robot_status(server, robot_id)
    assert status["connected"] and status["fps"] > 5 and status["latency_ms"] is not None


async def test_moves_execute_in_order_with_the_calibrated_pin_pulses(server, robots):
    robot_id, token, trial = new_robot_trial(server, "moves")
    robot = robots(server.url, token)
    async with trial.seat("commander"), trial.seat("driver") as driver:
        await driver.event("phase", phase="localizing", timeout=ROBOT_START_S)
        await driver.event("frame")  # the robot is connected: the trial runs
        for i, action in enumerate(["forward", "left", "right", "forward"]):
            await driver.send("move", action=action, move_id=f"m{i}")
            executed = await driver.event("move_executed", move_id=f"m{i}")
            assert executed["payload"]["outcome"] == "ok", executed["payload"]
    order = [(e.payload["move_id"], e.payload["action"]) for e in trial_events(server, trial, "move_executed")]
    assert order == [("m0", "forward"), ("m1", "left"), ("m2", "right"), ("m3", "forward")]
    # forward: both forward pins (GPIO4 left, GPIO17 right); left: GPIO17 + GPIO14 (left backward);
    # right: GPIO4 + GPIO18 (right backward). Each pulse lasts its calibrated time.
    found = pulses(robot.pin_log())
    assert [p for p, _, _ in found] == ["GPIO4", "GPIO17", "GPIO17", "GPIO14", "GPIO4", "GPIO18", "GPIO4", "GPIO17"]
    # Never shorter than calibrated (the move -> calibration mapping itself is tests/robot_client's);
    # late by what a loaded machine's scheduler adds, which a quarter second bounds: a pulse held
    # behind other work (the event loop, a frame) would be later still.
    lasted = [s for _, s, _ in found]
    expected = [0.3, 0.3, 0.2, 0.2, 0.25, 0.25, 0.3, 0.3]
    assert all(want - 0.01 <= got <= want + 0.25 for got, want in zip(lasted, expected, strict=True)), lasted
    assert robot_status(server, robot_id)["last_ack"]["status"] == "done"


async def test_a_move_is_refused_while_the_robot_is_not_connected_and_the_trial_waits(server, robots):
    robot_id, token, trial = new_robot_trial(server, "late")
    cookies = {"robotslang_session": server.services.sessions.issue(1)}
    async with (
        httpx.AsyncClient(base_url=server.url, cookies=cookies) as http,
        trial.seat("commander"),
        trial.seat("driver") as driver,
    ):

        async def dashboard() -> dict | None:
            trials = (await http.get("/experimenter/api/trials")).json()["trials"]
            return next((t for t in trials if t["trial_id"] == trial.id), None)

        waiting = await until(
            lambda: _when(dashboard(), lambda t: t and t["seats"]["commander"] and t["seats"]["driver"]),
            what="both participants on the dashboard",
        )
        assert waiting["phase"] == "waiting" and waiting["waiting_for"] == ["robot"]
        assert waiting["seats"] == {"commander": True, "driver": True, "robot": False}
        welcome = await driver.wait_for(lambda m: m["type"] == "welcome")
        assert welcome["seats_needed"] == ["commander", "driver", "robot"] and "robot" not in welcome["connected"]
        await driver.send("move", action="forward", move_id="early")
        refused = await driver.moved("early")
        assert refused["outcome"] == "refused"
        assert refused["reason"] == "the trial is waiting for the robot to connect"
        assert "phase" not in driver.kinds()

        robots(server.url, token)  # a fresh process: slow to start on a loaded machine
        await driver.event("phase", phase="localizing", timeout=ROBOT_START_S)
        started = await dashboard()
        assert started["waiting_for"] == [] and started["seats"]["robot"] and not started["paused"]
        await driver.send("move", action="forward", move_id="later")
        later = await driver.event("move_executed", move_id="later", timeout=ROBOT_START_S)
        assert later["payload"]["outcome"] == "ok", later["payload"].get("reason")
    kinds = [
        (e.kind, e.payload.get("role", e.payload.get("phase", e.payload.get("reason"))))
        for e in trial_events(server, trial)
        if e.kind in ("connect", "phase", "paused", "resumed")
    ]
    # The trial started (and its clock with it) only once the rover had joined; it was never "paused".
    before_start = kinds[: kinds.index(("phase", "localizing")) + 1]
    assert before_start == [
        ("connect", "commander"),
        ("connect", "driver"),
        ("connect", "robot"),
        ("phase", "localizing"),
    ]


async def _when(value, predicate):
    """`value` (awaited) when it satisfies `predicate`, else None: for `until` on an HTTP answer."""
    value = await value
    return value if predicate(value) else None


class Proxy:
    """A TCP relay between the rover and the server that can go silent (a dead Wi-Fi link)."""

    def __init__(self, port: int) -> None:
        self.target = port
        self.frozen = False
        self.port = 0

    async def start(self) -> None:
        self.server = await asyncio.start_server(self._client, "127.0.0.1", 0)
        self.port = self.server.sockets[0].getsockname()[1]

    async def _client(self, reader, writer) -> None:
        up_reader, up_writer = await asyncio.open_connection("127.0.0.1", self.target)
        await asyncio.gather(self._pipe(reader, up_writer), self._pipe(up_reader, writer), return_exceptions=True)
        for w in (writer, up_writer):
            w.close()

    async def _pipe(self, reader, writer) -> None:
        while data := await reader.read(65536):
            if not self.frozen:
                writer.write(data)
                await writer.drain()

    def close(self) -> None:
        self.server.close()


async def test_losing_the_link_stops_the_motors_within_the_watchdog_and_the_trial_resumes(server, robots):
    robot_id, token, trial = new_robot_trial(server, "link")
    proxy = Proxy(server.port)
    await proxy.start()
    robot = robots(f"http://127.0.0.1:{proxy.port}", token, calibration=Calibration(forward_s=1.8))
    try:
        async with trial.seat("commander"), trial.seat("driver") as driver:
            await driver.event("phase", phase="localizing", timeout=ROBOT_START_S)
            await driver.event("frame")
            await driver.send("move", action="forward", move_id="long")
            await until(lambda: any(e["state"] > 0 for e in robot.pin_log()), what="the pulse to start")
            await asyncio.sleep(0.2)
            seen = len(driver.received)
            proxy.frozen = True
            frozen_ns = time.monotonic_ns()
            stop = await until(
                lambda: [e for e in robot.pin_log() if e["pin"] == "GPIO4" and e["state"] == 0],
                timeout=3,
                what="the motors to stop",
            )
            stopped_after_s = (stop[0]["t_ns"] - frozen_ns) / 1e9
            # Stopped by the rover's own watchdog: the last ping was at most 0.1 s before the freeze.
            assert stopped_after_s <= WATCHDOG_S + 0.05, stopped_after_s
            executed = await driver.event("move_executed", move_id="long")
            assert executed["payload"]["outcome"] == "refused"
            await driver.event("paused", reason="disconnect:robot", start=seen)
            proxy.frozen = False
            await driver.event("resumed", reason="disconnect:robot", timeout=ROBOT_START_S, start=seen)
            await driver.send("move", action="left", move_id="after")
            after = await driver.event("move_executed", move_id="after")
            assert after["payload"]["outcome"] == "ok", after["payload"].get("reason")
    finally:
        proxy.close()
    print(f"motors stopped {stopped_after_s * 1000:.0f} ms after the link went silent")


async def test_a_restarted_client_reconnects_and_the_trial_continues(server, robots):
    robot_id, token, trial = new_robot_trial(server, "restart")
    first = robots(server.url, token)
    await until(lambda: robot_status(server, robot_id)["connected"], timeout=ROBOT_START_S, what="the robot to connect")
    async with trial.seat("commander"), trial.seat("driver") as driver:
        await driver.event("phase", phase="localizing")
        await driver.event("frame")
        await driver.send("move", action="forward", move_id="before")
        assert (await driver.event("move_executed", move_id="before"))["payload"]["outcome"] == "ok"
        seen = len(driver.received)
        first.proc.kill()
        first.proc.wait()
        await driver.event("paused", reason="disconnect:robot", start=seen)
        robots(server.url, token)
        await driver.event("resumed", reason="disconnect:robot", timeout=ROBOT_START_S, start=seen)
        await driver.event("frame", start=seen)
        await driver.send("move", action="right", move_id="after")
        assert (await driver.event("move_executed", move_id="after"))["payload"]["outcome"] == "ok"
    kinds = [
        e.kind
        for e in trial_events(server, trial)
        if e.kind in ("connect", "disconnect", "paused", "resumed")
        and e.payload.get("role", e.payload.get("reason", "")).endswith("robot")
    ]
    assert kinds == ["connect", "disconnect", "paused", "connect", "resumed"]
    assert trial_events(server, trial, "phase")[-1].payload["phase"] == "localizing"


async def test_a_wrong_token_is_refused(server, robots):
    robot_id, token, trial = new_robot_trial(server, "wrong")
    robot = robots(server.url, token + "x")
    assert robot.proc.wait(timeout=ROBOT_START_S) == 3
    assert "the server refused this robot: auth: unknown robot token" in robot.stop()
    assert not robot_status(server, robot_id)["connected"]
    assert not [e for e in trial_events(server, trial, "connect") if e.payload["role"] == "robot"]


async def test_malformed_and_oversized_messages_get_an_error_and_change_nothing(server, robots):
    robot_id, token, trial = new_robot_trial(server, "garbage")
    url = f"ws://127.0.0.1:{server.port}/ws/robot"
    async with (
        trial.seat("commander"),
        trial.seat("driver") as driver,
        websockets.connect(url, max_size=None, compression=None) as ws,
    ):
        await ws.send(json.dumps({"type": "hello", "protocol": 1, "token": token, "role": "driver"}))
        assert json.loads(await ws.recv())["type"] == "welcome"
        await driver.event("phase", phase="localizing")
        await ws.send(pack_frame(1, time.monotonic_ns(), 8, 8, TINY_JPEG))
        await driver.event("frame")
        before = [(e.kind, e.payload) for e in trial_events(server, trial)]
        jpeg = b"\xff\xd8" + bytes(MAX_FRAME_BYTES)
        bad = [
            "{not json",
            json.dumps({"type": "dance"}),
            json.dumps([1, 2]),
            b"JUNK" + bytes(40),
            pack_frame(2, time.monotonic_ns(), 8, 8, jpeg),
        ]
        errors = []
        for message in bad:
            await ws.send(message)
            while (reply := json.loads(await ws.recv()))["type"] != "error":
                assert reply["type"] == "ping"
            errors.append(reply["error"])
        # The link is still up: a good frame after the bad ones reaches the Driver.
        seen = len(driver.received)
        await ws.send(pack_frame(3, time.monotonic_ns(), 8, 8, TINY_JPEG))
        await driver.event("frame", start=seen)
        after = [(e.kind, e.payload) for e in trial_events(server, trial)]
    assert "not JSON" in errors[0] and "unknown message type 'dance'" in errors[1]
    assert "'type'" in errors[2] and "expected b'RSF1'" in errors[3] and "limit is" in errors[4]
    added = after[len(before) :]
    assert after[: len(before)] == before
    assert [k for k, _ in added] == ["bad_message"] * 5 + ["frame"]
    assert all(p["role"] == "robot" for k, p in added[:5])


async def test_overhead_frames_are_logged_but_never_reach_a_seat(server, robots):
    _, rover_token, trial = new_robot_trial(server, "table")
    _, overhead_token, _ = new_robot_trial(server, "table-camera", role="overhead")
    robots(server.url, rover_token)
    robots(server.url, overhead_token, role="overhead", fps=5)
    async with trial.seat("commander") as commander, trial.seat("driver") as driver:
        await driver.event("phase", phase="localizing", timeout=ROBOT_START_S)
        await until(
            lambda: len(trial_events(server, trial, "frame")) >= 20
            and any(e.payload["source"] == "overhead" for e in trial_events(server, trial, "frame")),
            timeout=ROBOT_START_S,
            what="overhead frames in the log",
        )
    sources = {e.payload["source"] for e in trial_events(server, trial, "frame")}
    assert sources == {"driver", "overhead"}
    assert all(m["payload"]["source"] == "driver" for m in frame_events(driver))
    assert not frame_events(commander)


async def test_the_experimenter_registers_robots_and_sees_their_links(server, robots):
    cookies = {"robotslang_session": server.services.sessions.issue(1)}
    async with httpx.AsyncClient(base_url=server.url, cookies=cookies, headers={"Origin": server.url}) as http:
        http.headers["X-CSRF-Token"] = page_csrf_token((await http.get("/experimenter")).text)
        made = (await http.post("/experimenter/api/robots", data={"name": "api rover", "role": "driver"})).json()
        assert made["backend"] == f"robot:{made['id']}" and len(made["token"]) >= 40
        again = await http.post("/experimenter/api/robots", data={"name": "api rover"})
        assert again.status_code == 400 and "already exists" in again.json()["detail"]
        robots(server.url, made["token"])
        await until(
            lambda: robot_status(server, made["id"])["fps"] > 5, timeout=ROBOT_START_S, what="frames from the new robot"
        )
        rows = (await http.get("/experimenter/api/robots")).json()["robots"]
        mine = next(r for r in rows if r["id"] == made["id"])
        assert mine["connected"] and mine["name"] == "api rover" and mine["latency_ms"] < 50
        assert "token" not in mine and "token_hash" not in mine
    async with httpx.AsyncClient(base_url=server.url) as anonymous:
        assert (await anonymous.get("/experimenter/api/robots")).status_code in (303, 307)


async def test_the_dashboard_page_shows_each_robot_and_offers_the_rover_for_trials(server, robots):
    robot_id, token, trial = new_robot_trial(server, "dashboard")
    cookies = {"robotslang_session": server.services.sessions.issue(1)}
    async with httpx.AsyncClient(base_url=server.url, cookies=cookies) as http:

        def robot_row(page: str) -> str:
            return re.search(rf'<tr data-robot="{robot_id}">.*?</tr>', page, re.S).group(0)

        page = (await http.get("/experimenter")).text
        assert "not connected" in robot_row(page)
        assert f'<option value="robot:{robot_id}">dashboard (rover)</option>' in page
        robots(server.url, token)
        await until(
            lambda: robot_status(server, robot_id)["fps"] > 5, timeout=ROBOT_START_S, what="frames from the robot"
        )
        async with trial.seat("commander"), trial.seat("driver") as driver:
            await driver.event("phase", phase="localizing", timeout=ROBOT_START_S)
            await driver.send("move", action="left", move_id="seen")
            await driver.event("move_executed", move_id="seen", timeout=ROBOT_START_S)
            row = robot_row((await http.get("/experimenter")).text)
    cells = dict(re.findall(r'<td class="(\w+)">(.*?)</td>', row, re.S))
    assert cells["name"] == "dashboard" and cells["role"] == "driver" and cells["link"] == "connected"
    assert float(cells["fps"]) > 5 and cells["latency"].endswith(" ms") and cells["ack"] == "left done"


async def test_frames_are_not_recorded_while_a_dropped_seat_pauses_the_trial(server, robots):
    robot_id, token, trial = new_robot_trial(server, "pause-rec")
    robots(server.url, token)

    def recorded() -> int:
        with server.services.db() as db:
            return len(db.scalars(select(FrameRow.id).where(FrameRow.trial_id == trial.id)).all())

    async with trial.seat("commander") as commander:
        async with trial.seat("driver") as driver:
            await driver.event("phase", phase="localizing", timeout=ROBOT_START_S)
            await until(lambda: recorded() >= 5, timeout=ROBOT_START_S, what="frames recorded")
        await commander.wait_for(lambda m: m.get("type") == "status" and "disconnect:driver" in m["paused"])
        await asyncio.sleep(0.3)  # a frame already on its way to the disk lands
        paused_at = recorded()
        await asyncio.sleep(1.5)  # 15 frames/s from the rover meanwhile
        assert recorded() == paused_at, "frames recorded while the trial waited for the Driver"
        async with trial.seat("driver"):
            await until(lambda: recorded() >= paused_at + 5, timeout=10, what="recording again once resumed")

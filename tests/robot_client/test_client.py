"""The rover client in-process against a scripted server on loopback: mock motors (real gpiozero
pin objects), synthetic camera."""

from __future__ import annotations

import asyncio
import json
import time
from contextlib import asynccontextmanager

import pytest

from robot_client.calibration import Calibration
from robot_client.camera import CameraSettings, FrameGrabber, SyntheticCamera
from robot_client.client import LinkRefused, LinkSettings, RobotClient
from robot_client.motors import Motors, mock_factory

pytestmark = pytest.mark.anyio

CALIBRATION = Calibration(forward_s=0.2, left_s=0.15, right_s=0.25, max_move_s=2.0)


@asynccontextmanager
async def running_client(server, token="good", calibration=CALIBRATION, fps=30.0, pin_log=None):
    factory = mock_factory(pin_log)
    motors = Motors(calibration, factory)
    grabber = FrameGrabber(SyntheticCamera(160, 120), CameraSettings(160, 120, fps, 70))
    client = RobotClient(LinkSettings(server.url, token, backoff_initial_s=0.05), grabber, motors)
    task = asyncio.create_task(client.run())
    try:
        yield client, factory, task
    finally:
        task.cancel()
        await asyncio.gather(task, return_exceptions=True)
        grabber.stop()
        motors.close()


def pin(factory, name):
    return next(p for info, p in factory.pins.items() if info.name == name)


def on_spans(p) -> list[float]:
    """Durations (s) the pin spent non-zero, from gpiozero's recorded state history."""
    spans, states = [], p.states
    for prev, cur in zip(states, states[1:]):
        if prev.state and not cur.state:
            spans.append(cur.timestamp)
    return spans


async def test_hello_then_frames_with_rising_sequence_and_capture_time(scripted_server):
    async with running_client(scripted_server):
        await asyncio.wait_for(scripted_server.connected.wait(), 3)
        await asyncio.sleep(0.5)
    hello = scripted_server.hellos[0]
    assert hello["type"] == "hello" and hello["token"] == "good" and hello["role"] == "driver"
    frames = scripted_server.frames
    assert len(frames) >= 8
    assert all(b.seq > a.seq and b.capture_ns > a.capture_ns for a, b in zip(frames, frames[1:]))
    assert (frames[0].width, frames[0].height) == (160, 120)


async def test_pings_are_answered_with_the_robot_clock(scripted_server):
    async with running_client(scripted_server):
        pong = await scripted_server.next("pong")
    assert pong["id"] >= 1 and abs(pong["robot_ns"] - time.monotonic_ns()) < 5e9


async def test_moves_run_their_calibrated_pulse_and_are_acknowledged(scripted_server):
    async with running_client(scripted_server) as (_, factory, _):
        await asyncio.wait_for(scripted_server.connected.wait(), 3)
        for move_id, action in [("m1", "forward"), ("m2", "left"), ("m3", "right")]:
            await scripted_server.send({"type": "move", "id": move_id, "action": action})
            ack = await scripted_server.next("ack")
            assert (ack["id"], ack["action"], ack["status"]) == (move_id, action, "done")
            assert ack["finished_ns"] - ack["started_ns"] == pytest.approx(CALIBRATION.duration(action) * 1e9, abs=40e6)
    # forward: both forward pins; left: right-forward + left-backward; right: the mirror.
    assert on_spans(pin(factory, "GPIO4")) == [pytest.approx(0.2, abs=0.04), pytest.approx(0.25, abs=0.04)]
    assert on_spans(pin(factory, "GPIO17")) == [pytest.approx(0.2, abs=0.04), pytest.approx(0.15, abs=0.04)]
    assert on_spans(pin(factory, "GPIO14")) == [pytest.approx(0.15, abs=0.04)]
    assert on_spans(pin(factory, "GPIO18")) == [pytest.approx(0.25, abs=0.04)]


async def test_a_move_during_a_move_is_refused_busy_not_queued(scripted_server):
    async with running_client(scripted_server) as (_, factory, _):
        await asyncio.wait_for(scripted_server.connected.wait(), 3)
        await scripted_server.send({"type": "move", "id": 1, "action": "forward"})
        await scripted_server.send({"type": "move", "id": 2, "action": "left"})
        refused = await scripted_server.next("ack")
        done = await scripted_server.next("ack")
        await asyncio.sleep(0.3)
    assert (refused["id"], refused["status"], refused["reason"]) == (2, "refused", "busy")
    assert (done["id"], done["status"]) == (1, "done")
    assert on_spans(pin(factory, "GPIO14")) == []  # the left turn never ran


async def test_unknown_action_and_stop_are_refused_with_their_reason(scripted_server):
    async with running_client(scripted_server, calibration=Calibration(forward_s=1.5)) as (_, factory, _):
        await asyncio.wait_for(scripted_server.connected.wait(), 3)
        await scripted_server.send({"type": "move", "id": "a", "action": "backward"})
        unknown = await scripted_server.next("ack")
        await scripted_server.send({"type": "move", "id": "b", "action": "forward"})
        await asyncio.sleep(0.2)
        await scripted_server.send({"type": "stop"})
        stopped = await scripted_server.next("ack")
    assert (unknown["status"], unknown["reason"]) == ("refused", "unknown")
    assert (stopped["id"], stopped["status"], stopped["reason"]) == ("b", "refused", "stopped")
    assert on_spans(pin(factory, "GPIO4")) == [pytest.approx(0.2, abs=0.05)]


async def test_watchdog_stops_the_motors_when_the_server_falls_silent(scripted_server, tmp_path):
    log = tmp_path / "pins.jsonl"
    async with running_client(scripted_server, calibration=Calibration(forward_s=1.8), pin_log=log) as (_, factory, _):
        await asyncio.wait_for(scripted_server.connected.wait(), 3)
        await scripted_server.send({"type": "move", "id": 1, "action": "forward"})
        await asyncio.sleep(0.1)
        scripted_server.pinging = False
        silent_from = time.monotonic_ns()
        ack = await scripted_server.next("ack")
    assert (ack["status"], ack["reason"]) == ("refused", "stopped")
    changes = [json.loads(line) for line in log.read_text().splitlines() if '"GPIO4"' in line]
    assert [c["state"] for c in changes] == [0.6, 0.0]
    # The last ping came at most 0.1 s before the silence began; the watchdog is 0.5 s.
    assert 0.35 < (changes[1]["t_ns"] - silent_from) / 1e9 <= 0.55


async def test_malformed_server_messages_get_an_error_and_change_nothing(scripted_server):
    async with running_client(scripted_server) as (_, factory, _):
        await asyncio.wait_for(scripted_server.connected.wait(), 3)
        for bad, words in [
            ("{oops", "not JSON"),
            ('{"type": "dance"}', "unknown message type 'dance'"),
            (b"\x00\x01", "no binary messages"),
            ('{"type": "move", "action": "forward"}', "needs an 'id'"),
        ]:
            await scripted_server.send(bad)
            error = await scripted_server.next("error")
            assert error["code"] == "bad_message" and words in error["error"]
        await scripted_server.send({"type": "move", "id": 9, "action": "forward"})
        assert (await scripted_server.next("ack"))["status"] == "done"
    (span,) = on_spans(pin(factory, "GPIO4"))
    # The pulse's calibrated 0.2 s; a loaded machine's sleeps overshoot, never end early.
    assert 0.16 <= span <= 0.35, span


async def test_wrong_token_is_refused_without_retrying(scripted_server):
    async with running_client(scripted_server, token="bad") as (_, _, task):
        with pytest.raises(LinkRefused, match="unknown robot token"):
            await asyncio.wait_for(task, 3)
    assert len(scripted_server.hellos) == 1


async def test_reconnects_after_the_server_drops_the_link_and_starts_stopped(scripted_server):
    async with running_client(scripted_server, calibration=Calibration(forward_s=1.5)) as (_, factory, _):
        await asyncio.wait_for(scripted_server.connected.wait(), 3)
        await scripted_server.send({"type": "move", "id": 1, "action": "forward"})
        await asyncio.sleep(0.1)
        await scripted_server.connections[0].close()
        async with asyncio.timeout(3):
            while len(scripted_server.connections) < 2:
                await asyncio.sleep(0.02)
        assert pin(factory, "GPIO4").state == 0
        await scripted_server.send({"type": "move", "id": 2, "action": "right"})
        ack = await scripted_server.next("ack")
        while ack["id"] != 2:  # move 1's "stopped" ack may or may not have made it out
            ack = await scripted_server.next("ack")
        assert ack["status"] == "done"
    assert len(scripted_server.hellos) == 2

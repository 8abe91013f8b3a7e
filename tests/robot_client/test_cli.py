"""`robotslang-robot` as a real process: calibration walk-through, refusals, signals."""

from __future__ import annotations

import asyncio
import json
import signal
import subprocess
import sys
import time

import pytest

from robot_client.calibration import Calibration

ROBOT = [sys.executable, "-m", "robot_client"]


def read_pin_log(path) -> list[dict]:
    return [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []


def test_calibrate_scales_each_pulse_by_target_over_measured(tmp_path):
    path = tmp_path / "cal.json"
    Calibration(forward_s=0.1, left_s=0.1, right_s=0.1).save(path)
    answers = (
        "\n".join(
            [
                "",
                "14",  # forward: first pulse went 14 cm, twice the 7 cm wanted
                "",
                "",  # second pulse accepted
                "",
                "",  # left accepted as is
                "",
                "abc",
                "",
                "90",
                "",
                "",  # right: a typo, then 90 degrees, then accepted
            ]
        )
        + "\n"
    )
    result = subprocess.run(
        ROBOT + ["calibrate", "--motors", "mock", "--calibration", str(path)],
        input=answers,
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert result.returncode == 0, result.stderr
    assert "'abc' is not a number" in result.stdout
    cal = Calibration.load(path)
    assert (cal.forward_s, cal.left_s, cal.right_s) == (0.05, 0.1, 0.05)


def test_calibrate_abandoned_leaves_the_file_unchanged(tmp_path):
    path = tmp_path / "cal.json"
    Calibration(forward_s=0.1).save(path)
    before = path.read_text()
    result = subprocess.run(
        ROBOT + ["calibrate", "--motors", "mock", "--calibration", str(path)],
        input="\n7\n",
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert result.returncode != 0 and "the file was not changed" in result.stderr
    assert path.read_text() == before


def test_bad_calibration_file_is_named_and_nothing_starts(tmp_path):
    path = tmp_path / "cal.json"
    path.write_text('{"forward_s": -1}')
    result = subprocess.run(
        ROBOT
        + [
            "--server",
            "http://127.0.0.1:9",
            "--token",
            "t",
            "--camera",
            "synthetic",
            "--motors",
            "mock",
            "--calibration",
            str(path),
        ],
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert result.returncode == 2
    assert "cal.json: forward_s must be in (0, max_move_s=2.0]" in result.stderr


def test_bad_camera_and_server_are_named():
    result = subprocess.run(
        ROBOT + ["--server", "http://127.0.0.1:9", "--token", "t", "--camera", "/no/such.mp4", "--motors", "mock"],
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert result.returncode == 2 and "--camera '/no/such.mp4' is not a camera index" in result.stderr
    result = subprocess.run(
        ROBOT + ["--server", "127.0.0.1:9", "--token", "t"], capture_output=True, text=True, timeout=30
    )
    assert result.returncode == 2 and "--server must be a URL like http://HOST:PORT" in result.stderr


@pytest.mark.anyio
async def test_wrong_token_exits_with_the_servers_reason(scripted_server):
    process = await asyncio.create_subprocess_exec(
        *ROBOT,
        "--server",
        scripted_server.url,
        "--token",
        "bad",
        "--camera",
        "synthetic",
        "--motors",
        "mock",
        stderr=asyncio.subprocess.PIPE,
    )
    _, stderr = await asyncio.wait_for(process.communicate(), 20)
    assert process.returncode == 3
    assert "the server refused this robot: auth: unknown robot token" in stderr.decode()


@pytest.mark.anyio
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
async def test_signal_stops_a_running_move_before_exit(scripted_server, tmp_path, sig):
    cal, pins = tmp_path / "cal.json", tmp_path / "pins.jsonl"
    Calibration(forward_s=1.8).save(cal)
    process = await asyncio.create_subprocess_exec(
        *ROBOT,
        "--server",
        scripted_server.url,
        "--token",
        "good",
        "--camera",
        "synthetic",
        "--motors",
        "mock",
        "--calibration",
        str(cal),
        "--pin-log",
        str(pins),
        stderr=asyncio.subprocess.PIPE,
    )
    try:
        await asyncio.wait_for(scripted_server.connected.wait(), 20)
        await scripted_server.send({"type": "move", "id": 1, "action": "forward"})
        async with asyncio.timeout(3):
            while not any(e["state"] > 0 for e in read_pin_log(pins)):
                await asyncio.sleep(0.01)
        signalled_ns = time.monotonic_ns()
        process.send_signal(sig)
        _, stderr = await asyncio.wait_for(process.communicate(), 10)
    finally:
        if process.returncode is None:
            process.kill()
            await process.wait()
    assert process.returncode == 0, stderr.decode()
    log = read_pin_log(pins)
    gpio4 = [e for e in log if e["pin"] == "GPIO4"]
    assert [e["state"] for e in gpio4] == [0.6, 0.0]
    assert 0 <= gpio4[-1]["t_ns"] - signalled_ns < 100e6  # stopped at once, not after the 1.8 s pulse
    assert f"motors stopped: {sig.name} received" in stderr.decode()


def test_the_client_loads_none_of_the_servers_packages():
    code = (
        "import sys, robot_client.cli, robot_client.calibrate; "
        "bad = sorted(m for m in sys.modules if m.split('.')[0] in ('app', 'sim', 'models', 'torch', 'fastapi')); "
        "print(bad); sys.exit(1 if bad else 0)"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stdout + result.stderr


@pytest.mark.anyio
async def test_a_video_file_camera_streams_resized_frames_in_a_loop(scripted_server, tmp_path):
    import cv2
    import numpy as np

    video = tmp_path / "table.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10, (64, 48))
    for i in range(5):  # shorter than the test: the file must loop
        writer.write(np.full((48, 64, 3), 40 * i, np.uint8))
    writer.release()
    process = await asyncio.create_subprocess_exec(
        *ROBOT,
        "--server",
        scripted_server.url,
        "--token",
        "good",
        "--role",
        "overhead",
        "--camera",
        str(video),
        "--width",
        "32",
        "--height",
        "24",
        "--fps",
        "20",
        stderr=asyncio.subprocess.PIPE,
    )
    try:
        await asyncio.wait_for(scripted_server.connected.wait(), 20)
        async with asyncio.timeout(10):
            while len(scripted_server.frames) < 12:
                await asyncio.sleep(0.05)
    finally:
        process.send_signal(signal.SIGTERM)
        await asyncio.wait_for(process.communicate(), 10)
    assert scripted_server.hellos[0]["role"] == "overhead"
    assert {(f.width, f.height) for f in scripted_server.frames} == {(32, 24)}

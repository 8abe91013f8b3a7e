"""`robotslang robot virtual` end to end: the real server (`robotslang serve`) and the software
rover as separate processes on loopback, a trial on that rover driven over real websockets, and
the rover's truth file read as only a test harness may."""

from __future__ import annotations

import asyncio
import base64
import math
import signal
import subprocess
import sys

import cv2
import numpy as np
import pytest
from websockets.asyncio.server import serve

from app.rover.virtual.truth import TruthSample, read_truth
from bench.live import REPO, SeatClient
from robot_client.calibration import Calibration
from sim.core.geometry import GRID_STEP_M, TURN_RAD
from sim.robot.camera import FrontCamera
from sim.robot.rover import BODY_RADIUS_M, Rover, RoverPose
from sim.robot.tracking import OverheadTracker
from tests.app.live import cli
from tests.app.rover_lab import MAZE, START_S, settled, turned, until
from tests.robot_client.scripted_server import ScriptedServer

pytestmark = pytest.mark.anyio


def pose_of(sample: TruthSample) -> RoverPose:
    return RoverPose(sample.x, sample.y, sample.theta)


def decode(frame_event: dict) -> np.ndarray:
    jpeg = base64.b64decode(frame_event["jpeg"])
    image = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
    assert image is not None, "a frame that is not a JPEG"
    return image


async def frame_after(driver: SeatClient, t_ns: int) -> np.ndarray:
    """The first frame at the Driver captured after server time `t_ns`."""
    event = await driver.wait_for(
        lambda m: m.get("type") == "event" and m["kind"] == "frame" and m["payload"]["capture_ns"] > t_ns
    )
    return decode(event)


async def test_a_driver_drives_the_virtual_rover_frames_acks_truth_and_a_wall(lab, maze, start, tmp_path, trials):
    robot_id, token = lab.register("virtual rover")
    trial = trials.new(lab.server, MAZE, backend=f"robot:{robot_id}")
    truth = tmp_path / "truth.jsonl"
    lab.rover(
        token, "--truth", str(truth), "--seed", "5", "--fps", "10", "--start", f"{start.x},{start.y},{start.theta}"
    )
    camera = FrontCamera()
    async with trial.seat("commander"), trial.seat("driver") as driver:
        await driver.event("phase", phase="localizing", timeout=START_S)
        first = decode(await driver.event("frame"))
        assert first.shape == (camera.height, camera.width, 3)
        assert pose_of(settled(truth)[0]) == start and settled(truth)[0].move_id == 0

        async def move(action: str, move_id: str) -> tuple[TruthSample, TruthSample, np.ndarray]:
            before = settled(truth)[-1]
            await driver.send("move", action=action, move_id=move_id)
            executed = await driver.event("move_executed", move_id=move_id, timeout=START_S)
            # The rover cannot sense a collision, real or virtual: every pulse that ran is "ok".
            assert executed["payload"]["outcome"] == "ok", executed["payload"]
            after = settled(truth)[-1]
            assert after.move_id == before.move_id + 1 and after.action == action
            return before, after, await frame_after(driver, executed["t_ns"])

        for i, action in enumerate(["forward", "left", "right", "left", "right"]):
            before, after, frame = await move(action, f"m{i}")
            step = math.hypot(after.x - before.x, after.y - before.y)
            if action == "forward":
                assert abs(step - GRID_STEP_M) < 0.008 and not after.collision
                along = math.atan2(after.y - before.y, after.x - before.x)
                assert abs(turned(before.theta, along)) < math.radians(3)
            else:
                sign = 1 if action == "left" else -1
                assert abs(turned(before.theta, after.theta) - sign * TURN_RAD) < math.radians(4)
                assert step < 0.005
            # The frame shows the rover where the truth says it is, not where it was.
            seen = frame.astype(np.float32)
            here = np.abs(seen - camera.ideal(maze, after.x, after.y, after.theta)).mean()
            there = np.abs(seen - camera.ideal(maze, before.x, before.y, before.theta)).mean()
            assert here < there, (action, here, there)

        # Straight on into the wall: the body stops at it and stays there.
        for i in range(14):
            before, after, _ = await move("forward", f"w{i}")
            if after.collision:
                break
        else:
            raise AssertionError("the rover never reached the wall ahead")
        assert BODY_RADIUS_M <= Rover(maze, pose_of(after)).clearance_m(after.x, after.y) < BODY_RADIUS_M + 0.01
        _, pressed, _ = await move("forward", "again")
        assert pressed.collision and pose_of(pressed) == pose_of(after)
    during = [s for s in read_truth(truth) if s.moving]
    assert during and all(s.move_id >= 1 for s in during)  # sampled while the pulses ran
    t = [s.t_ns for s in read_truth(truth)]
    assert t == sorted(t)


async def test_killing_the_server_stops_the_rover_and_it_reconnects_when_the_server_returns(
    lab, start, tmp_path, trials
):
    robot_id, token = lab.register("resilient rover")
    trial = trials.new(lab.server, MAZE, backend=f"robot:{robot_id}")
    truth, timings = tmp_path / "truth.jsonl", tmp_path / "calibration.json"
    Calibration(forward_s=1.8).save(timings)  # a long pulse, so the link dies during it
    lab.rover(
        token,
        "--truth",
        str(truth),
        "--noise",
        "none",
        "--fps",
        "5",
        "--calibration",
        str(timings),
        "--start",
        f"{start.x},{start.y},{start.theta}",
    )
    async with trial.seat("commander"), trial.seat("driver") as driver:
        await driver.event("phase", phase="localizing", timeout=START_S)
        await driver.send("move", action="forward", move_id="long")
        await until(
            lambda: any(s.moving and math.hypot(s.x - start.x, s.y - start.y) > 0.005 for s in read_truth(truth)),
            what="the pulse to move the rover",
        )
        lab.server.kill()
        stopped = (await until(lambda: settled(truth)[1:], what="the rover to stop"))[0]
    travelled = math.hypot(stopped.x - start.x, stopped.y - start.y)
    assert stopped.move_id == 1 and 0.005 < travelled < GRID_STEP_M * 0.8, travelled  # cut short
    await asyncio.sleep(0.5)
    assert settled(truth)[-1] == stopped and not read_truth(truth)[-1].moving  # and it stays stopped

    lab.server.start()
    async with trial.seat("commander"), trial.seat("driver") as driver:
        # The rover may reconnect before or after the seats do: read the resumption from the log.
        await until(
            lambda: any(
                e.kind == "resumed" and e.payload["reason"] == "disconnect:robot"
                for e in lab.services.log.load(trial.id)
            ),
            what="the trial to resume for the rover",
        )
        await driver.send("move", action="left", move_id="after")
        executed = await driver.event("move_executed", move_id="after", timeout=START_S)
        assert executed["payload"]["outcome"] == "ok", executed["payload"]
    turn = settled(truth)[-1]
    assert turn.move_id == 2 and turn.action == "left"
    assert turn.theta == pytest.approx((stopped.theta + TURN_RAD) % (2 * math.pi))
    assert (turn.x, turn.y) == (stopped.x, stopped.y)


async def test_the_virtual_overhead_camera_films_the_driver_rover_where_its_truth_says(lab, start, tmp_path, trials):
    robot_id, token = lab.register("filmed rover")
    _, camera_token = lab.register("table camera", role="overhead")
    trial = trials.new(lab.server, MAZE, backend=f"robot:{robot_id}")
    truth = tmp_path / "truth.jsonl"
    lab.rover(
        token, "--truth", str(truth), "--seed", "2", "--fps", "5", "--start", f"{start.x},{start.y},{start.theta}"
    )
    lab.rover(camera_token, "--role", "overhead", "--truth", str(truth), "--fps", "2")

    def overhead_after(t_ns: int) -> dict | None:
        return next(
            (
                e.payload
                for e in lab.services.log.load(trial.id)
                if e.kind == "frame" and e.payload["source"] == "overhead" and e.payload["capture_ns"] > t_ns
            ),
            None,
        )

    async with trial.seat("commander") as commander, trial.seat("driver") as driver:
        await driver.event("phase", phase="localizing", timeout=START_S)
        # The camera may have joined before the rover's first truth line (an empty table then),
        # and its first frames are stamped on arrival until the clocks are matched: let it settle.
        await until(
            lambda: sum(
                e.kind == "frame" and e.payload["source"] == "overhead" for e in lab.services.log.load(trial.id)
            )
            >= 3,
            what="overhead frames",
        )
        for i, action in enumerate(["forward", "left", "forward"]):
            await driver.send("move", action=action, move_id=f"o{i}")
            executed = await driver.event("move_executed", move_id=f"o{i}", timeout=START_S)
            pose = settled(truth)[-1]
            frame = await until(
                lambda: overhead_after(executed["t_ns"]),  # noqa: B023  (awaited in this iteration)
                what="an overhead frame after the move",
            )
            jpeg = (lab.settings.frames_dir / frame["path"]).read_bytes()
            # A fresh tracker for each frame: the view is under test here, not the smoothing.
            seen = OverheadTracker().update(jpeg, frame["capture_ns"])
            assert seen is not None, f"no rover found in the overhead frame after {action}"
            assert math.hypot(seen.x - pose.x, seen.y - pose.y) < 0.02, (seen, pose)
            assert abs(turned(pose.theta, seen.heading)) < math.radians(3), (seen, pose)
    heard = commander.received + driver.received
    assert not [m for m in heard if m.get("kind") == "frame" and m["payload"]["source"] == "overhead"]


async def test_on_the_wire_the_virtual_rover_is_the_real_client(tmp_path):
    """The same hello fields, RSF1 frames and acks as `robotslang-robot`, against a scripted server."""
    seen = {}
    for kind in ("real", "virtual"):
        server = ScriptedServer()
        async with serve(server.handler, "127.0.0.1", 0, compression=None, max_size=None) as ws_server:
            url = f"ws://127.0.0.1:{ws_server.sockets[0].getsockname()[1]}/ws/robot"
            if kind == "real":
                command = [sys.executable, "-m", "robot_client", "--camera", "synthetic", "--motors", "mock"]
            else:
                command = [
                    sys.executable,
                    "-c",
                    "from app.cli import main; main()",
                    "robot",
                    "virtual",
                    "--maze",
                    MAZE,
                    "--seed",
                    "1",
                ]
            proc = subprocess.Popen(
                command + ["--server", url, "--token", "good", "--fps", "5"],
                cwd=REPO,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
            try:
                await asyncio.wait_for(server.connected.wait(), START_S)
                await server.send({"type": "move", "id": "w1", "action": "left"})
                ack = await server.next("ack", timeout=START_S)
                await until(
                    lambda: len(server.frames) >= 2,  # noqa: B023  (awaited in this iteration)
                    what=f"frames from the {kind} client",
                )
            finally:
                proc.send_signal(signal.SIGTERM)
                assert proc.wait(timeout=20) == 0
            seen[kind] = (server.hellos[0], ack, server.frames)
    (real_hello, real_ack, _), (hello, ack, frames) = seen["real"], seen["virtual"]
    assert set(hello) == set(real_hello) and set(hello["camera"]) == set(real_hello["camera"])
    assert {k: hello[k] for k in ("protocol", "client", "role", "watchdog_s")} == {
        k: real_hello[k] for k in ("protocol", "client", "role", "watchdog_s")
    }
    assert hello["camera"]["source"] == "virtual"
    assert set(ack) == set(real_ack) and ack["status"] == real_ack["status"] == "done"
    assert ack["finished_ns"] - ack["started_ns"] >= Calibration().left_s * 1e9
    assert [(f.width, f.height) for f in frames[:2]] == [(640, 480)] * 2
    assert frames[1].seq == frames[0].seq + 1 and frames[1].capture_ns > frames[0].capture_ns


def test_bad_options_are_refused_by_name(tmp_path, maze):
    env = {"ROBOTSLANG_DATA_DIR": str(tmp_path / "var"), "ROBOTSLANG_SECRET_KEY": "k"}
    base = ["robot", "virtual", "--server", "http://127.0.0.1:9", "--token", "t"]
    cases = [
        (["--maze", "nowhere"], "--maze", "unknown maze 'nowhere'"),
        (["--maze", MAZE, "--noise", "wild"], "--noise", "unknown noise model 'wild'"),
        (["--maze", MAZE, "--start", "1,2"], "--start", "expected X,Y,THETA"),
        (["--maze", MAZE, "--start", "0,0,0"], "--start", "within 0.067 m"),
        (["--maze", MAZE, "--role", "overhead"], "--truth", "films the driver rover's truth file"),
        (["--maze", MAZE, "--role", "pilot"], "--role", "expected one of driver, overhead"),
    ]
    for args, hint, text in cases:
        done = cli(*base, *args, env=env)
        message = " ".join(done.stderr.replace("│", " ").split())
        assert done.returncode == 2 and hint in message and text in message, (args, done.stderr)


def test_the_truth_follower_sees_only_whole_lines_and_follows_a_restarted_rover(tmp_path):
    from app.rover.virtual.truth import TruthFollower, TruthLog

    path = tmp_path / "truth.jsonl"
    follower = TruthFollower(path)
    assert follower.poll() is None  # no rover yet: an empty table
    log = TruthLog(path)
    log.write(TruthSample(1, 0.5, 0.5, 0.0, 0, None, False, False))
    log.write(TruthSample(2, 0.6, 0.5, 0.0, 1, "forward", False, False))
    assert follower.poll().t_ns == 2
    with open(path, "a") as half:  # a line still being written
        half.write('{"t_ns": 3, "x": 0.7')
    assert follower.poll().t_ns == 2 and [s.t_ns for s in read_truth(path)] == [1, 2]
    log.close()
    restarted = TruthLog(path)  # the rover starts again: the file is replaced
    restarted.write(TruthSample(9, 1.0, 1.0, 1.0, 0, None, False, False))
    assert follower.poll() == TruthSample(9, 1.0, 1.0, 1.0, 0, None, False, False)
    restarted.close()
    follower.close()

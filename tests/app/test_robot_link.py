"""The server's end of a robot link: clock offset from pings (with a robot clock that differs
from the server's, which loopback never shows), frame times, acknowledgements, and robot tokens
on SQLite and PostgreSQL."""

from __future__ import annotations

import asyncio
import time

import pytest
from sqlalchemy import select

from app.backends.base import BackendUnavailable
from app.clock import ServerClock
from app.db.engine import make_engine, make_sessionmaker, upgrade
from app.db.models import Robot
from app.rover.links import RobotLink
from app.rover.records import RobotSetupError, create_robot, hash_token, robot_for_token
from robot_client.protocol import FrameHeader

SKEW_NS = 5_000_000_000  # the robot's monotonic clock reads 5 s ahead of the server's


CLOCK = ServerClock()


def server_clock_bounds(mono_ns: int, call):
    """Run `call()`; the server-clock time of the monotonic instant `mono_ns` as computed inside it
    lies in the returned [lo, hi]: mapping reads the clock twice, and the bound is how long the
    call took, measured around it (not a guess, so it holds under any load)."""
    before = time.monotonic_ns()
    result = call()
    took = time.monotonic_ns() - before
    exact = mono_ns + CLOCK._offset_ns  # ServerClock is monotonic time plus a fixed offset
    return result, exact - took, exact


def make_link(sent: list[dict]) -> RobotLink:
    return RobotLink(1, "rover", "driver", sent.append, CLOCK)


def answer_ping(link: RobotLink, sent: list[dict], rtt_ns: int, answered_after_ns: int | None = None) -> None:
    """The robot answers the last ping: it reads its clock `answered_after_ns` after the ping left."""
    link.ping()
    ping = sent[-1]
    at = ping["server_ns"] + (rtt_ns // 2 if answered_after_ns is None else answered_after_ns)
    link.on_pong({"type": "pong", "id": ping["id"], "robot_ns": at + SKEW_NS}, ping["server_ns"] + rtt_ns)


def test_offset_comes_from_the_fastest_round_trip():
    sent: list[dict] = []
    link = make_link(sent)
    assert link.offset_ns is None and link.latency_ms is None
    # Slow round trips answered off-centre would bias the estimate; the fastest one wins.
    answer_ping(link, sent, rtt_ns=80_000_000, answered_after_ns=70_000_000)
    answer_ping(link, sent, rtt_ns=2_000_000)
    answer_ping(link, sent, rtt_ns=60_000_000, answered_after_ns=5_000_000)
    assert link.offset_ns == SKEW_NS
    assert link.latency_ms == pytest.approx(1.0)


def test_robot_times_land_on_the_server_clock():
    sent: list[dict] = []
    link = make_link(sent)
    answer_ping(link, sent, rtt_ns=1_000_000)
    taken = time.monotonic_ns() - 30_000_000  # captured 30 ms ago on the server's clock
    frame, lo, hi = server_clock_bounds(
        taken, lambda: link.on_frame(FrameHeader(1, taken + SKEW_NS, 640, 480), b"\xff\xd8", time.monotonic_ns())
    )
    assert lo <= frame.capture_ns <= hi
    assert (frame.width, frame.height) == (640, 480)


def test_frame_times_never_run_ahead_of_arrival_nor_back():
    sent: list[dict] = []
    link = make_link(sent)
    answer_ping(link, sent, rtt_ns=1_000_000)
    arrival = time.monotonic_ns()
    future = link.on_frame(FrameHeader(1, arrival + SKEW_NS + 10**9, 8, 8), b"", arrival)
    same = link.on_frame(FrameHeader(2, arrival + SKEW_NS - 10**9, 8, 8), b"", arrival)
    assert future.capture_ns <= CLOCK.now_ns()
    assert same.capture_ns > future.capture_ns


def test_frames_before_the_first_pong_are_stamped_at_arrival():
    link = make_link([])
    arrival = time.monotonic_ns()
    frame, lo, hi = server_clock_bounds(arrival, lambda: link.on_frame(FrameHeader(1, 123, 8, 8), b"", arrival))
    assert lo <= frame.capture_ns <= hi


@pytest.mark.anyio
async def test_a_move_returns_its_ack_and_a_lost_link_fails_it():
    sent: list[dict] = []
    link = make_link(sent)
    answer_ping(link, sent, rtt_ns=1_000_000)
    move = asyncio.create_task(link.move("left"))
    await asyncio.sleep(0)
    request = sent[-1]
    assert request["type"] == "move" and request["action"] == "left"
    robot_now = time.monotonic_ns() + SKEW_NS
    _, lo, hi = server_clock_bounds(
        robot_now - SKEW_NS,
        lambda: link.on_ack(
            {
                "type": "ack",
                "id": request["id"],
                "action": "left",
                "status": "done",
                "started_ns": robot_now - 200_000_000,
                "finished_ns": robot_now,
            },
            time.monotonic_ns(),
        ),
    )
    ack = await move
    assert ack["status"] == "done"
    assert lo <= ack["finished_ns"] <= hi  # on the server clock
    assert link.status()["last_ack"]["status"] == "done"

    pending = asyncio.create_task(link.move("forward"))
    await asyncio.sleep(0)
    link.close()
    with pytest.raises(BackendUnavailable, match="lost its link during the move"):
        await pending
    with pytest.raises(BackendUnavailable, match="not connected"):
        await link.move("forward")


def test_robot_tokens_are_stored_hashed_and_checked(any_db_settings):
    engine = make_engine(any_db_settings)
    upgrade(any_db_settings, engine)
    db = make_sessionmaker(engine)
    with db.begin() as session:
        robot, token = create_robot(session, "rover 1")
        create_robot(session, "table camera", "overhead")
    with db() as session:
        stored = session.scalar(select(Robot).where(Robot.name == "rover 1"))
        assert stored.token_hash == hash_token(token) and token not in stored.token_hash
        assert robot_for_token(session, token).id == robot.id
        assert robot_for_token(session, token[:-1] + "x") is None
    with pytest.raises(RobotSetupError, match="robot 'rover 1' already exists"), db.begin() as session:
        create_robot(session, "rover 1")
    with pytest.raises(RobotSetupError, match="robot role 'camera'"), db.begin() as session:
        create_robot(session, "rover 2", "camera")
    with db() as session:
        assert sorted(session.scalars(select(Robot.name))) == ["rover 1", "table camera"]
    engine.dispose()

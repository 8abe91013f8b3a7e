"""What an independent attacker tried against a running server (issue 27): spoofed client
addresses, a second Host header, locking a lab out, sockets outliving a logout, forged rover
frames and a flood of chat; and a Driver's flood of moves (issue 35). Each test runs a real
server on a loopback port."""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import random
import socket
import subprocess
import sys
import time
from pathlib import Path

import cv2
import httpx
import numpy as np
import pytest
import websockets
from pydantic import ValidationError

from app.settings import Settings
from app.trial.refusals import REFUSED_RUN_S
from bench.live import REPO
from robot_client.protocol import pack_frame
from sim.trial.state import fold
from tests.app.live import (
    PASSWORD,
    add_experimenter,
    browser,
    experimenter_client,
    log_in,
    page_csrf_token,
    platform_rate,
    session_cookie,
    submit_login,
)
from tests.app.trial_play import start_trial
from tests.app.wire_rover import Rover, rover_trial


def from_address(server, address: str = "127.0.0.1") -> httpx.Client:
    """A browser at `address` (patient: a login hashes a password)."""
    return browser(server.url, address)


def guesses(client: httpx.Client, names, forwarded_for=None) -> list[int]:
    """One wrong password per name (the login form, its page's token), with an X-Forwarded-For
    header per guess from `forwarded_for(i)`; the statuses."""
    token = page_csrf_token(client.get("/").text)
    statuses = []
    for i, name in enumerate(names):
        headers = {"X-Forwarded-For": forwarded_for(i)} if forwarded_for else {}
        answer = client.post("/login", data={"name": name, "password": "guess", "csrf_token": token}, headers=headers)
        statuses.append(answer.status_code)
        if answer.status_code == 429:
            break
    return statuses


def logged_in(answer: httpx.Response) -> bool:
    """The login form's answer led to the dashboard (the home page also lists participants)."""
    return answer.status_code == 200 and answer.url.path == "/experimenter"


# -- client addresses ------------------------------------------------------------------
def test_a_client_naming_another_address_in_x_forwarded_for_is_still_limited(server):
    # No proxy configured: the header is the client's own word, and the socket's peer is the client.
    statuses = guesses(from_address(server), [f"nobody{i}" for i in range(200)], lambda i: f"10.1.{i}.{i % 250}")
    assert statuses[-1] == 429, f"{len(statuses)} guesses, none refused"
    assert statuses.count(401) == 20  # LOGIN_LIMIT_PER_ADDRESS


@pytest.mark.settings(trusted_proxies=["127.0.0.1"])
def test_behind_a_trusted_proxy_the_right_most_address_it_did_not_add_is_the_client(server):
    add_experimenter(server)
    # nginx appends the address it saw; whatever the client wrote comes before it.
    statuses = guesses(from_address(server), [f"nobody{i}" for i in range(100)], lambda i: f"10.2.{i}.1, 203.0.113.7")
    assert statuses[-1] == 429 and statuses.count(401) == 20
    # Another client behind the same proxy is not limited by it.
    other = from_address(server)
    other.headers["X-Forwarded-For"] = "203.0.113.8"
    assert logged_in(submit_login(other, "eve", PASSWORD))
    with pytest.raises(ValidationError, match="not an address or network"):
        Settings(trusted_proxies=["*"])


def test_serve_refuses_uvicorns_forwarded_allow_ips(tmp_path):
    # Compose files once trusted every client with FORWARDED_ALLOW_IPS="*": now a start that fails.
    done = subprocess.run(
        [sys.executable, "-c", "from app.cli import main; main()", "serve", "--port", "1"],
        env={**os.environ, "FORWARDED_ALLOW_IPS": "*", "ROBOTSLANG_DATA_DIR": str(tmp_path)},
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode != 0 and "ROBOTSLANG_TRUSTED_PROXIES" in done.stderr


# -- Host ------------------------------------------------------------------------------
def raw_status(port: int, headers: list[str]) -> int:
    """The status line's code for `GET /` with exactly these header lines."""
    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        s.sendall(("GET / HTTP/1.1\r\n" + "".join(f"{h}\r\n" for h in headers) + "Connection: close\r\n\r\n").encode())
        reply = b""
        while b"\r\n" not in reply and (chunk := s.recv(4096)):
            reply += chunk
    return int(reply.split(b" ", 2)[1])


def test_a_request_with_two_host_headers_is_refused(server):
    own = f"Host: 127.0.0.1:{server.port}"
    assert raw_status(server.port, [own]) == 200
    assert raw_status(server.port, [own, "Host: evil.example"]) == 400
    assert raw_status(server.port, ["Host: evil.example", own]) == 400
    assert raw_status(server.port, [own, own]) == 400


# -- lockout ---------------------------------------------------------------------------
def test_guessing_locks_out_the_guesser_not_the_experimenter(server):
    add_experimenter(server)
    attacker = from_address(server, "127.0.0.2")
    statuses = guesses(attacker, ["eve"] * 10)
    assert statuses == [401] * 5 + [429]  # LOGIN_LIMIT_PER_ACCOUNT, from that address
    assert submit_login(attacker, "eve", PASSWORD).status_code == 429
    # The experimenter, at another address, logs in while the attacker is locked out.
    assert logged_in(submit_login(from_address(server, "127.0.0.3"), "eve", PASSWORD))


# -- a flood of chat -------------------------------------------------------------------
@pytest.mark.settings(**platform_rate())
def test_a_flood_of_chat_from_one_seat_is_rate_limited_and_nothing_accepted_is_lost(settings, server, trials):
    flood = 1000
    trial = trials.new()

    async def attack() -> tuple[list[dict], list[dict], float]:
        async with (
            trial.seat("commander") as commander,
            trial.seat("driver") as driver,
        ):
            await start_trial(commander, driver)
            await driver.send("chat", text="before the flood")
            await commander.event("chat", text="before the flood")
            start, began = len(commander.received), time.monotonic()
            for i in range(flood):
                await commander.send("chat", text=f"flood {i}")
            # A seat's messages are handled in order: once this is heard, so was the flood
            # (sent again while the server, still at the flood, refuses it).
            for _ in range(30):
                await commander.send("chat", text="after the flood")
                with contextlib.suppress(AssertionError):
                    await driver.event("chat", text="after the flood", timeout=2)
                    break
            return commander.received[start:], driver.received, time.monotonic() - began

    to_commander, to_driver, took_s = asyncio.run(attack())
    server.stop()  # what it still had to record is recorded
    logged = chats(server, trial.id)
    flood_logged = [text for text in logged if text.startswith("flood ")]
    # The burst went through, then at most the rate; what was refused is nowhere in the log.
    assert flood_logged[: settings.seat_message_burst] == [f"flood {i}" for i in range(settings.seat_message_burst)]
    assert len(flood_logged) <= settings.seat_message_burst + settings.seat_message_rate_per_s * took_s
    assert flood_logged == sorted(flood_logged, key=lambda t: int(t.split()[1]))
    # The sender was told (once per run of refused messages, not a thousand times).
    errors = [m for m in to_commander if m.get("type") == "error"]
    assert errors and all(e["code"] == "rate_limited" and e["retry_after_s"] > 0 for e in errors)
    assert len(errors) <= len(flood_logged) - settings.seat_message_burst + 1
    # Nothing recorded is lost, the partner heard exactly what was recorded, and the seat still speaks.
    heard = [m["payload"]["text"] for m in to_driver if m.get("type") == "event" and m["kind"] == "chat"]
    assert logged[0] == "before the flood" and logged[-1] == "after the flood"
    assert heard == logged


# -- a flood of moves ------------------------------------------------------------------
@pytest.mark.settings(**platform_rate(), min_move_interval_s=Settings.model_fields["min_move_interval_s"].default)
@pytest.mark.parametrize("gap_s", [0.0, 0.008], ids=["as-fast-as-it-can", "the-issues-2.4-s"])
def test_a_flood_of_moves_is_rate_limited_and_its_refusals_logged_as_runs(settings, server, trial, gap_s):
    flood = 300

    async def attack() -> tuple[list[dict], float]:
        async with (
            trial.seat("commander") as commander,
            trial.seat("driver") as driver,
        ):
            await start_trial(commander, driver)
            start, began = len(driver.received), time.monotonic()
            for i in range(flood):
                await driver.send("move", action="left", move_id=f"f{i}")
                await asyncio.sleep(gap_s)
            # A seat's messages are taken in order: once this is heard, so was the flood.
            for _ in range(30):
                await driver.send("chat", text="after the flood")
                with contextlib.suppress(AssertionError):
                    await commander.event("chat", text="after the flood", timeout=2)
                    break
            return driver.received[start:], time.monotonic() - began

    to_driver, took_s = asyncio.run(attack())
    server.stop()  # the last run of refusals is logged as the trial's runtime closes
    log = server.services.log.load(trial.id)
    # Every request counted against the seat's rate, executed or refused: the flood was told to slow down.
    limited = [m for m in to_driver if m.get("type") == "error" and m["code"] == "rate_limited"]
    refusals = [m for m in to_driver if m.get("type") == "move_refused"]
    executed = [m for m in to_driver if m.get("kind") == "move_executed"]
    assert limited and executed and refusals
    taken = len(refusals) + len(executed)
    assert taken <= settings.seat_message_burst + settings.seat_message_rate_per_s * took_s
    # Each refused request was answered; the log counts them all, in a handful of events.
    runs = [e for e in log if e.kind == "moves_refused"]
    assert sum(e.payload["count"] for e in runs) == len(refusals) == fold(log).refused
    assert [e.payload["move_id"] for e in log if e.kind == "move_executed"] == [
        m["payload"]["move_id"] for m in executed
    ]
    move_events = [e for e in log if e.kind in ("move_requested", "move_executed", "moves_refused")]
    # A run ends at an executed move, a change of reason or REFUSED_RUN_S after its first request.
    assert len(runs) <= 2 * len(executed) + took_s / REFUSED_RUN_S + 1 and len(move_events) < flood / 10


def chats(server, trial_id: int) -> list[str]:
    return [e.payload["text"] for e in server.services.log.load(trial_id) if e.kind == "chat"]


# -- forged rover frames ---------------------------------------------------------------
def test_a_forged_rover_frame_is_refused_and_nothing_of_it_is_recorded(settings, server, trials):
    trial_id, rover_token = rover_trial(server.services)
    trial = trials.of(trial_id)
    forgeries = {
        "not a JPEG": b"\xff\xd8" + random.Random(27).randbytes(20_000) + b"\xff\xd9",
        "but the JPEG is 8x8": cv2.imencode(".jpg", np.zeros((8, 8, 3), np.uint8))[1].tobytes(),
    }

    async def play() -> tuple[list[dict], list[dict]]:
        async with (
            Rover(server.ws_url, rover_token) as rover,
            trial.seat("commander") as commander,
            trial.seat("driver") as driver,
        ):
            await start_trial(commander, driver)
            await rover.frame(1, rover.now())
            await driver.event("frame")
            for seq, payload in enumerate(forgeries.values(), start=2):
                await rover.ws.send(pack_frame(seq, rover.now(), 320, 240, payload))
                deadline = time.monotonic() + 10
                while len(rover.errors) < seq - 1:
                    assert time.monotonic() < deadline, "the forged frame got no error reply"
                    await asyncio.sleep(0.05)
            seen = len(driver.received)
            await rover.frame(4, rover.now())  # the link is up: a real frame is still recorded
            await driver.event("frame", start=seen)
            return rover.errors, driver.received

    errors, to_driver = asyncio.run(play())
    events = server.services.log.load(trial_id)
    assert [e["code"] for e in errors] == ["bad_message"] * 2
    for error, expected in zip(errors, forgeries, strict=True):
        assert expected in error["error"], error
    bad = [e for e in events if e.kind == "bad_message"]
    assert [e.payload["role"] for e in bad] == ["robot"] * 2 and [e.payload["error"] for e in bad] == [
        e["error"] for e in errors
    ]
    frames = [e for e in events if e.kind == "frame"]
    assert len(frames) == 2 and len([m for m in to_driver if m.get("kind") == "frame"]) == 2
    assert sorted(p.name for p in settings.frames_dir.rglob("*.jpg")) == sorted(
        Path(e.payload["path"]).name for e in frames
    )


# -- sockets after logout --------------------------------------------------------------
def test_an_experimenters_watch_sockets_close_at_logout_and_at_a_password_change(settings, server, trial):
    env = {"ROBOTSLANG_DATA_DIR": str(settings.data_dir), "ROBOTSLANG_SECRET_KEY": settings.secret_key}
    experimenter = experimenter_client(server.services, server.url)

    async def watch_until_closed(end_login) -> tuple[list[str], int]:
        """A watch opened while logged in: what it heard, and its close code after `end_login`."""
        async with websockets.connect(
            f"ws://127.0.0.1:{server.port}/ws/watch/{trial.id}",
            additional_headers={"Cookie": session_cookie(experimenter)},
        ) as watch:
            assert json.loads(await watch.recv())["type"] == "welcome"
            async with trial.seat("commander") as commander:
                await commander.send("chat", text="before")
                heard = [await asyncio.wait_for(watch.recv(), 10)]
                while '"before"' not in heard[-1]:
                    heard.append(await asyncio.wait_for(watch.recv(), 10))
                await asyncio.to_thread(end_login)
                await commander.send("chat", text="after")
                with pytest.raises(websockets.ConnectionClosed) as closed:
                    while True:
                        heard.append(await asyncio.wait_for(watch.recv(), 10))
            return heard, closed.value.rcvd.code

    heard, code = asyncio.run(watch_until_closed(lambda: experimenter.post("/logout")))
    assert code == 4401 and not any('"after"' in m for m in heard)
    experimenter = log_in(server.url, "eve", PASSWORD)

    def change_password() -> None:
        done = subprocess.run(
            [sys.executable, "-c", "from app.cli import main; main()", "admin", "password", "eve"]
            + ["--password", "a new horse"],
            env={**os.environ, **env},
            cwd=REPO,
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert done.returncode == 0, done.stderr

    # From another process: the socket's own check sees the login gone within a second.
    _, code = asyncio.run(watch_until_closed(change_password))
    assert code == 4401


# -- grace after a crash ---------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.settings(grace_period_s=12.0)
def test_after_a_crash_a_participant_away_before_it_keeps_only_the_grace_that_remained(
    settings, server_process, trials
):
    grace_s, away_before_crash_s = settings.grace_period_s, 4.1
    server = server_process()
    services = server.services
    trial = trials.new(server)
    server.start()
    killed_after_s: list[float] = []
    try:

        async def until_the_crash() -> None:
            async with trial.seat("commander") as commander:
                async with trial.seat("driver") as driver:
                    await start_trial(commander, driver)
                await commander.event("disconnect", role="driver")
                left = time.monotonic()
                await asyncio.sleep(away_before_crash_s)
                server.kill()
                killed_after_s.append(time.monotonic() - left)  # on a loaded machine, more than asked

        asyncio.run(until_the_crash())
        server.start()  # reopens the running trial, and its grace timers, at once
        deadline = time.monotonic() + 3 * grace_s
        while fold(events := services.log.load(trial.id)).phase != "aborted":
            assert time.monotonic() < deadline, "the trial never aborted"
            time.sleep(0.2)
    finally:
        server.stop()
    left_driver = next(e.t_ns for e in events if e.kind == "disconnect" and e.payload["role"] == "driver")
    restarted = next(e.t_ns for e in events if e.kind == "restarted")
    aborted = events[-1].t_ns
    assert events[-1].kind == "phase" and events[-1].payload["phase"] == "aborted"
    # The Driver's grace ran on from where it was at the crash (the log notes it every second
    # while they are away), not afresh; the Commander's, begun at the restart, is the longer.
    grace_after_restart_s = (aborted - restarted) / 1e9
    away_logged_s = (max(e.t_ns for e in events if e.t_ns < restarted) - left_driver) / 1e9
    # Noted about every second up to the crash (a loaded server notes late; the Commander hears
    # the disconnect a little after the server logs it).
    assert killed_after_s[0] - 2.5 <= away_logged_s <= killed_after_s[0] + 1.0
    remained_s = grace_s - away_logged_s
    # A busy loop fires timers late, but never by the 4 s a fresh grace would add.
    assert remained_s - 0.1 <= grace_after_restart_s <= remained_s + 2.0

"""The server against a hostile network: cross-site requests, password guessing, stolen cookies,
old join links, framing and DNS rebinding. Each test runs a real server on a loopback port."""

from __future__ import annotations

import asyncio
import hashlib
import os
import re
import secrets
import subprocess
import sys
import time

import httpx
import pytest
import websockets
from alembic import command
from sqlalchemy import select

from app.db.engine import alembic_config, make_engine
from app.db.models import Experimenter, Participant, Trial
from app.i18n import Language
from app.routes.seat_ws import TRIAL_OVER
from app.security import SESSION_COOKIE, InvalidToken, Seat, SeatTokens
from app.study.config import StudyFiles, template
from bench.live import REPO
from tests.app.live import (
    PASSWORD,
    add_experimenter,
    browser,
    log_in,
    page_csrf_token,
    submit_login,
)
from tests.app.trial_play import start_trial


def participants(server) -> list[str]:
    with server.services.db() as db:
        return list(db.scalars(select(Participant.name)))


def phase(server, trial_id: int) -> str:
    with server.services.db() as db:
        return db.get(Trial, trial_id).phase


def other_port_of(server) -> str:
    """Another origin of the same site: 127.0.0.1, another port (cookies do not tell ports apart)."""
    return f"http://127.0.0.1:{server.port + 1 if server.port < 65535 else server.port - 1}"


# -- cross-site request forgery --------------------------------------------------------
def test_a_page_on_another_port_cannot_create_participants_or_abort_a_trial(server, trials):
    add_experimenter(server)
    experimenter = log_in(server.url, "eve", PASSWORD)
    token = experimenter.headers["X-CSRF-Token"]
    trial = trials.new()
    foreign = other_port_of(server)

    def forged(path: str, data: dict | None = None, **headers) -> httpx.Response:
        """The experimenter's browser (its cookies) posting what another page sends."""
        with httpx.Client(base_url=server.url, cookies=experimenter.cookies, timeout=60) as client:
            return client.post(path, data=data or {"name": "Mallory"}, headers=headers, follow_redirects=True)

    # Another page's form or fetch: its own Origin, and at best a token it does not have.
    assert forged("/experimenter/participants", Origin=foreign).status_code == 403
    assert forged("/experimenter/participants", Origin=foreign, **{"X-CSRF-Token": token}).status_code == 403
    assert forged("/experimenter/participants", Origin="null").status_code == 403
    assert forged("/experimenter/participants", Referer=foreign + "/attack.html").status_code == 403
    # Even from this server's origin, a request without the page's token is refused.
    refused = forged("/experimenter/participants", Origin=server.url)
    assert refused.status_code == 403 and "token" in refused.json()["detail"]
    assert forged("/experimenter/participants", Origin=server.url, **{"X-CSRF-Token": "0" * 64}).status_code == 403
    assert forged("/experimenter/participants").status_code == 403, "no Origin and no Referer"
    assert forged("/experimenter/api/robots", Origin=foreign).status_code == 403
    assert "Mallory" not in participants(server)

    async def abort_attempts() -> None:
        async with (
            trial.seat("commander") as commander,
            trial.seat("driver") as driver,
        ):
            await start_trial(commander, driver)
            for headers in ({"Origin": foreign}, {"Origin": foreign, "X-CSRF-Token": token}, {}):
                answer = await asyncio.to_thread(forged, f"/experimenter/trials/{trial.id}/abort", **headers)
                assert answer.status_code == 403
            assert phase(server, trial.id) == "localizing"
            # The experimenter's own page still can (the token in its form, Referer for Origin).
            page = await asyncio.to_thread(
                forged,
                f"/experimenter/trials/{trial.id}/abort",
                {"csrf_token": token},
                Referer=server.url + "/experimenter",
            )
            assert page.status_code == 200
            await commander.event("phase", phase="aborted")

    asyncio.run(abort_attempts())
    experimenter.post("/experimenter/participants", data={"name": "Ada"})
    assert "Ada" in participants(server) and "Mallory" not in participants(server)


@pytest.mark.settings(allowed_origins=["https://lab.example"])
def test_allowed_origins_may_post_and_login_needs_the_home_pages_token(server):
    add_experimenter(server)
    client = browser(server.url)
    token = page_csrf_token(client.get("/").text)
    # Login CSRF: a form on another page cannot log this browser into an account.
    forged = client.post(
        "/login",
        data={"name": "eve", "password": PASSWORD, "csrf_token": token},
        headers={"Origin": other_port_of(server)},
    )
    assert forged.status_code == 403 and SESSION_COOKIE not in client.cookies
    tokenless = client.post("/login", data={"name": "eve", "password": PASSWORD})
    assert tokenless.status_code == 403 and SESSION_COOKIE not in client.cookies
    # A token is bound to its browser: another browser's token does not do.
    other_token = page_csrf_token(browser(server.url).get("/").text)
    assert (
        client.post("/login", data={"name": "eve", "password": PASSWORD, "csrf_token": other_token}).status_code == 403
    )
    page = client.post(
        "/login",
        data={"name": "eve", "password": PASSWORD, "csrf_token": token},
        headers={"Origin": "https://lab.example"},
    )
    assert page.status_code == 200 and "Participants" in page.text
    # After login the token changes with the session: the anonymous one no longer counts.
    assert client.post("/experimenter/participants", data={"name": "Ada", "csrf_token": token}).status_code == 403
    client.post("/experimenter/participants", data={"name": "Ada", "csrf_token": page_csrf_token(page.text)})
    assert "Ada" in participants(server) and "Mallory" not in participants(server)


def test_websocket_origins_compare_scheme_host_and_port(server, trial):
    host = server.url.removeprefix("http://")

    async def welcome(origin: str | None) -> dict:
        async with trial.seat("commander", origin=origin) as seat:
            return await seat.wait_for(lambda m: m.get("type") == "welcome")

    for origin in (other_port_of(server), f"https://{host}", "http://localhost.evil.example"):
        with pytest.raises(websockets.InvalidStatus):
            asyncio.run(welcome(origin))
    assert asyncio.run(welcome(server.url))["role"] == "commander"
    assert asyncio.run(welcome(None))["role"] == "commander", "scripts send no Origin"

    async def robot_socket(origin: str) -> None:
        robot_url = f"ws://{host}/ws/robot"
        async with websockets.connect(robot_url, origin=origin):
            pass

    with pytest.raises(websockets.InvalidStatus):
        asyncio.run(robot_socket(other_port_of(server)))


# -- logins ----------------------------------------------------------------------------
@pytest.mark.settings(login_limit_per_account="3/minute", login_limit_per_address="5/minute")
def test_failed_logins_are_limited_per_account_and_per_address(server):
    add_experimenter(server)
    add_experimenter(server, "zoe", "zoe's password")
    client = browser(server.url)
    assert [submit_login(client, "eve", "guess").status_code for _ in range(3)] == [401] * 3
    limited = submit_login(client, "eve", PASSWORD)
    assert limited.status_code == 429 and "too many login attempts" in limited.text
    assert 1 <= int(limited.headers["Retry-After"]) <= 60
    # Another account from the same address: two more attempts, then the address is limited too.
    assert "Participants" in submit_login(client, "zoe", "zoe's password").text
    client.post("/logout", data={"csrf_token": page_csrf_token(client.get("/experimenter").text)})
    assert submit_login(client, "zoe", "guess").status_code == 401
    assert submit_login(client, "nobody", "guess").status_code == 429


@pytest.mark.slow
@pytest.mark.settings(login_limit_per_account="1000/minute", login_limit_per_address="1000/minute")
def test_a_burst_of_wrong_logins_leaves_the_server_answering(server):
    burst = 40
    add_experimenter(server)
    client = browser(server.url)
    token = page_csrf_token(client.get("/").text)

    async def attack() -> tuple[list[int], int, int]:
        async with httpx.AsyncClient(
            base_url=server.url, cookies=client.cookies, headers={"Origin": server.url}, timeout=300
        ) as http:

            async def guess(i: int) -> int:
                name = "eve" if i % 2 else f"unknown{i}"
                answer = await http.post("/login", data={"name": name, "password": f"guess {i}", "csrf_token": token})
                return answer.status_code

            guesses = [asyncio.create_task(guess(i)) for i in range(burst)]
            await asyncio.sleep(0)
            home = await http.get("/")
            pending = sum(not g.done() for g in guesses)
            return await asyncio.gather(*guesses), home.status_code, pending

    statuses, home, pending = asyncio.run(attack())
    assert home == 200
    assert pending > 0, "GET / answered only after every password check"
    assert set(statuses) <= {401, 429} and len(statuses) == burst


def _scrypt_hash(password: str) -> str:
    """A hash as the platform stored them before argon2."""
    salt = secrets.token_bytes(16)
    return f"scrypt${salt.hex()}${hashlib.scrypt(password.encode(), salt=salt, n=2**14, r=8, p=1).hex()}"


def test_a_database_from_0001_opens_and_old_password_hashes_upgrade_at_login(settings, start_server):
    engine = make_engine(settings)
    config = alembic_config(settings)
    with engine.begin() as connection:
        config.attributes["connection"] = connection
        command.upgrade(config, "0001")
        connection.exec_driver_sql(
            "insert into experimenter (name, password_hash, created_at) values ('eve', ?, '2026-01-01 00:00:00')",
            (_scrypt_hash(PASSWORD),),
        )
    engine.dispose()
    server = start_server()  # on the database written above
    assert submit_login(browser(server.url), "eve", "wrong").status_code == 401
    with server.services.db() as db:
        assert db.scalar(select(Experimenter.password_hash)).startswith("scrypt$"), "no upgrade on failure"
    log_in(server.url, "eve", PASSWORD)
    with server.services.db() as db:
        upgraded = db.scalar(select(Experimenter.password_hash))
    assert upgraded.startswith("$argon2id$v=19$m=") and ",t=" in upgraded, "parameters are in the hash"
    log_in(server.url, "eve", PASSWORD)


# -- sessions --------------------------------------------------------------------------
def test_a_login_cookie_stops_working_at_logout_and_at_a_password_change(settings, server):
    env = {"ROBOTSLANG_DATA_DIR": str(settings.data_dir), "ROBOTSLANG_SECRET_KEY": settings.secret_key}
    add_experimenter(server)

    def opens_dashboard(cookie: str) -> bool:
        answer = httpx.get(server.url + "/experimenter", cookies={SESSION_COOKIE: cookie}, timeout=60)
        return answer.status_code == 200

    client = log_in(server.url, "eve", PASSWORD)
    stolen = client.cookies[SESSION_COOKIE]
    assert opens_dashboard(stolen)
    assert client.post("/logout").status_code == 200
    assert not opens_dashboard(stolen), "a copy of the cookie outlives the logout"

    client = log_in(server.url, "eve", PASSWORD)
    stolen = client.cookies[SESSION_COOKIE]
    done = subprocess.run(
        [
            sys.executable,
            "-c",
            "from app.cli import main; main()",
            "admin",
            "password",
            "eve",
            "--password",
            "a new horse",
        ],
        env={**os.environ, **env},
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0 and "password changed" in done.stdout, done.stderr
    assert not opens_dashboard(stolen)
    assert client.get("/experimenter").url.path == "/", "the browser is logged out too"
    log_in(server.url, "eve", "a new horse")
    done = subprocess.run(
        [
            sys.executable,
            "-c",
            "from app.cli import main; main()",
            "admin",
            "password",
            "nobody",
            "--password",
            "whatever-long",
        ],
        env={**os.environ, **env},
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode != 0 and "no experimenter 'nobody'" in done.stderr


# -- join links ------------------------------------------------------------------------
def test_a_join_link_closes_when_its_trial_ends(server, trials):
    add_experimenter(server)
    trial = trials.new()
    assert httpx.get(trial.play_url("commander")).status_code == 200
    log_in(server.url, "eve", PASSWORD).post(f"/experimenter/trials/{trial.id}/abort")
    assert phase(server, trial.id) == "aborted"
    page = httpx.get(trial.play_url("driver"))
    assert page.status_code == 410 and "this trial was stopped" in page.text and "<html" in page.text
    assert httpx.get(f"{server.url}/play/{trial.tokens['commander']}/map.png").status_code == 410

    async def connect() -> websockets.exceptions.ConnectionClosed:
        async with websockets.connect(f"{server.ws_url}?token={trial.tokens['commander']}") as seat:
            with pytest.raises(websockets.exceptions.ConnectionClosed) as closed:
                await asyncio.wait_for(seat.recv(), 5)
            return closed.value

    # The socket is closed at once with the code its page reloads on (then the 410 page above).
    closed = asyncio.run(connect())
    assert closed.rcvd.code == TRIAL_OVER and "this trial was stopped" in closed.rcvd.reason


@pytest.mark.settings(join_link_ttl_s=3.0)
def test_a_join_link_expires_after_its_ttl_but_an_open_seat_keeps_working(server, trial, trials):
    # Links issued now, not at the fixture's setup: on a loaded machine that alone can outlast a TTL.
    trial = trials.of(trial.id)
    assert httpx.get(trial.play_url("commander")).status_code == 200

    async def play() -> None:
        async with trial.seat("commander") as commander:
            await commander.wait_for(lambda m: m.get("type") == "welcome")
            await asyncio.sleep(4.2)  # link timestamps count whole seconds
            await commander.send("chat", text="still here")
            await commander.event("chat", text="still here")
        with pytest.raises(websockets.InvalidStatus):
            async with trial.seat("commander"):
                pass

    asyncio.run(play())
    page = httpx.get(trial.play_url("commander"))
    assert page.status_code == 410 and "expired" in page.text
    fresh = trials.of(trial.id)  # its links issued again
    assert httpx.get(fresh.play_url("commander")).status_code == 200


@pytest.mark.settings(join_link_ttl_s=1.0)
def test_an_expired_join_link_of_a_study_says_so_in_the_study_language(server, trial):
    StudyFiles.of(server.settings.data_dir).save(template("roboter").model_copy(update={"language": Language.de}))
    with server.services.db.begin() as db:
        db.get(Trial, trial.id).study = "roboter"
    time.sleep(2.2)  # link timestamps count whole seconds
    page = httpx.get(trial.play_url("commander"))
    assert page.status_code == 410 and '<html lang="de"' in page.text
    assert "Dieser Teilnahmelink ist abgelaufen" in page.text


# -- headers and host names ------------------------------------------------------------
def test_every_response_carries_the_security_headers(server, trial):
    paths = [
        "/",
        "/leaderboard",
        "/static/style.css",
        "/nowhere",
        "/experimenter",
        f"/play/{trial.tokens['commander']}",
        "/play/forged",
    ]
    for path in paths:
        answer = httpx.get(server.url + path)
        csp = answer.headers["content-security-policy"]
        assert "frame-ancestors 'none'" in csp and "script-src 'self'" in csp and "unsafe-inline" not in csp
        assert answer.headers["x-content-type-options"] == "nosniff"
        assert answer.headers["referrer-policy"] == "same-origin"
        assert answer.headers["x-frame-options"] == "DENY"


def test_inline_code_that_the_policy_would_block_is_absent_from_the_templates():
    for page in (REPO / "templates").glob("*.html"):
        text = page.read_text()
        assert not re.search(r"<script(?![^>]*\bsrc=)[^>]*>", text), f"{page.name}: inline script"
        assert "<style" not in text and " style=" not in text, f"{page.name}: inline style"
        assert not re.search(r"\son[a-z]+=", text), f"{page.name}: inline event handler"


@pytest.mark.settings(allowed_hosts=["lab.example"], allowed_origins=["https://study.example:8443"])
def test_the_host_header_must_name_this_server(server):
    def status(host: str) -> int:
        return httpx.get(server.url + "/", headers={"Host": host}).status_code

    # DNS rebinding: a page of evil.example whose name now points at this machine.
    assert status(f"evil.example:{server.port}") == 400
    assert status("lab.example.evil.example") == 400
    for served in (
        f"lab.example:{server.port}",
        "study.example",
        f"127.0.0.1:{server.port}",
        f"[::1]:{server.port}",
        f"192.168.1.20:{server.port}",
    ):
        assert status(served) == 200, served

    async def socket(host: str) -> None:
        async with websockets.connect(f"ws://{host}:{server.port}/ws/robot", host="127.0.0.1", port=server.port):
            pass

    with pytest.raises(websockets.InvalidStatus):
        asyncio.run(socket("evil.example"))


def test_by_default_only_loopback_names_are_served(settings, server):
    assert settings.allowed_hosts == ["127.0.0.1", "localhost", "[::1]"]
    assert httpx.get(server.url + "/", headers={"Host": f"localhost:{server.port}"}).status_code == 200
    assert httpx.get(server.url + "/", headers={"Host": "lab.example"}).status_code == 400


def test_a_seat_token_checked_once_still_refuses_every_forgery():
    # Genuine tokens are remembered (every message carries one); a forgery never is.
    tokens = SeatTokens("key-one")
    genuine = tokens.issue(7, "driver")
    assert tokens.verify(genuine) == Seat(7, "driver")
    assert tokens.verify(genuine) == Seat(7, "driver")
    for forged in (
        genuine[:-2] + ("xx" if not genuine.endswith("xx") else "yy"),
        SeatTokens("key-two").issue(7, "driver"),
    ):
        for _ in range(2):
            with pytest.raises(InvalidToken):
                tokens.verify(forged)

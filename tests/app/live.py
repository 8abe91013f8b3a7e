"""Helpers for the platform's tests: their settings, a real uvicorn server on a loopback port in a
thread or `robotslang serve` as a process, a trial's handle (its seats' tokens and links), an
experimenter's browser session and live view, and the command line. Tests take servers and trials
from conftest's fixtures; trials are set up and seats played by `bench.live`'s helpers (the
benchmarks drive the platform with them too)."""

from __future__ import annotations

import asyncio
import functools
import os
import re
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import httpx
import uvicorn
import websockets

from app.db.models import Experimenter
from app.main import build_services, create_app
from app.security import SEAT_ROLES, SESSION_COOKIE, hash_password
from app.serving import uvicorn_options
from app.settings import Settings
from bench.live import REPO, SeatClient, ServerProcess, free_port, make_trial, settings_env

PASSWORD = "correct horse"


class ServerThread:
    """`create_app(settings)` served by uvicorn on 127.0.0.1 in a background thread. Tests take one
    from conftest's fixtures (`server`, `start_server`, `cluster`), which stop it when the test ends."""

    def __init__(self, settings: Settings) -> None:
        self.settings = settings
        self.app = create_app(settings)
        self.services = self.app.state.services
        self.port = free_port()
        config = uvicorn.Config(
            self.app, host="127.0.0.1", port=self.port, log_level="warning", lifespan="on", **uvicorn_options(settings)
        )
        self.server = uvicorn.Server(config)
        self.thread = threading.Thread(target=self.server.run, daemon=True)
        self.stopped = False

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    @property
    def ws_url(self) -> str:
        return f"ws://127.0.0.1:{self.port}/ws/play"

    def start(self) -> ServerThread:
        """Serving: returns once the server answers."""
        self.thread.start()
        deadline = time.time() + 20
        while not self.server.started:
            if time.time() > deadline or not self.thread.is_alive():
                raise RuntimeError("test server did not start")
            time.sleep(0.02)
        return self

    def stop(self) -> None:
        """Shut down as the server does (what it still had to write is written); again: nothing."""
        if self.stopped:
            return
        self.stopped = True
        self.server.should_exit = True
        self.thread.join(timeout=20)
        self.services.engine.dispose()


class PlatformProcess(ServerProcess):
    """`robotslang serve` as a process on `settings` (what they set, passed in its environment),
    so a test can kill it and start it again; beside it, the platform's services on the same data in
    this process (to set up trials and read their logs). Tests take one from conftest's
    `server_process`, which builds it unstarted and stops it when the test ends."""

    def __init__(self, settings: Settings, workers: int = 1) -> None:
        super().__init__(settings_env(settings), workers=workers)
        self.settings = settings

    @functools.cached_property
    def services(self) -> Any:
        """Built when first asked for (a test that only watches the process needs none)."""
        return build_services(self.settings)

    def close(self) -> None:
        self.stop()
        if "services" in self.__dict__:
            self.services.engine.dispose()


class Served(Protocol):
    """A test server, in a thread or a process: where it serves, and its services."""

    services: Any

    @property
    def url(self) -> str: ...

    @property
    def ws_url(self) -> str: ...


@dataclass(frozen=True)
class TrialHandle:
    """A trial on a test server: its id, and its seats' join tokens by role (what the
    experimenter's join links carry). Tests take them from conftest's `trial` and `trials`."""

    id: int
    tokens: dict[str, str]
    url: str  # the server's
    ws_url: str  # its seats' socket

    @classmethod
    def on(cls, server: Served, trial_id: int) -> TrialHandle:
        """The handle of trial `trial_id` on `server`: a join token issued for each seat."""
        tokens = {role: server.services.seats.issue(trial_id, role) for role in SEAT_ROLES}
        return cls(trial_id, tokens, server.url, server.ws_url)

    def play_url(self, role: str) -> str:
        """The seat's join link: its page on the server."""
        return f"{self.url}/play/{self.tokens[role]}"

    def seat(self, role: str, origin: str | None = None) -> SeatClient:
        """The seat's websocket client (opened by `async with`)."""
        return SeatClient(self.ws_url, self.tokens[role], origin=origin)


class Trials:
    """Trials on a test server, `default()` unless another is named, as `TrialHandle`s. Tests
    take one from conftest's `trials`, whose default is the `server` fixture."""

    def __init__(self, default: Callable[[], Served]) -> None:
        self._default = default

    def new(self, on: Served | None = None, maze: str | None = None, **options) -> TrialHandle:
        """A new team's trial (`bench.live.make_trial`'s `options`) on `maze`, else the server's first."""
        server = on if on is not None else self._default()
        services = server.services
        return TrialHandle.on(server, make_trial(services, maze or services.mazes.names()[0], **options))

    def of(self, trial_id: int, on: Served | None = None) -> TrialHandle:
        """The handle of a trial the platform made (a study's, a rover's): its seats' tokens."""
        return TrialHandle.on(on if on is not None else self._default(), trial_id)


def page_csrf_token(page: str) -> str:
    """The CSRF token a page carries in `<meta name="csrf-token">` (what the page's scripts send)."""
    return re.search(r'<meta name="csrf-token" content="([^"]+)"', page).group(1)


def browser(base_url: str, address: str | None = None) -> httpx.Client:
    """A client that sends this server's Origin, as a browser does on the server's own pages. It
    waits as a browser would: the first dashboard imports the agents' libraries (seconds, more on a
    loaded machine), past httpx's 5 s default. From `address`, as far as the server can tell: its
    socket bound to that loopback address (all of 127.0.0.0/8 reaches this machine)."""
    transport = httpx.HTTPTransport(local_address=address) if address else None
    return httpx.Client(
        base_url=base_url, follow_redirects=True, headers={"Origin": base_url}, timeout=60, transport=transport
    )


def submit_login(client: httpx.Client, name: str, password: str) -> httpx.Response:
    """The home page's login form, filled in and sent with the page's token."""
    token = page_csrf_token(client.get("/").text)
    return client.post("/login", data={"name": name, "password": password, "csrf_token": token})


def log_in(base_url: str, name: str, password: str) -> httpx.Client:
    """An experimenter's browser, as far as the server can tell: it logs in with the home page's
    form, then sends the dashboard page's token on every request (as the page's scripts do)."""
    client = browser(base_url)
    page = submit_login(client, name, password)
    assert page.status_code == 200 and "Participants" in page.text, page.text[:300]
    client.headers["X-CSRF-Token"] = page_csrf_token(page.text)
    return client


def experimenter_client(services: Any, url: str, name: str = "eve", password: str = "correct horse") -> httpx.Client:
    """A new experimenter account in the server's database (`services`), logged in at `url`
    through the home page's form."""
    with services.db.begin() as db:
        db.add(Experimenter(name=name, password_hash=hash_password(password)))
    return log_in(url, name, password)


def session_cookie(client: httpx.Client) -> str:
    """The Cookie header of a logged-in client's session (for a websocket opened beside it)."""
    return f"{SESSION_COOKIE}={client.cookies[SESSION_COOKIE]}"


def wait_js(page, expression: str, timeout_s: float = 30.0) -> None:
    """Poll a JavaScript expression (or `() => ...` function) in `page` until it is truthy.
    Playwright's own wait_for_function polls through eval, which the pages' CSP rightly forbids."""
    deadline = time.monotonic() + timeout_s
    while not page.evaluate(expression):
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s} s waiting for {expression!r}")
        page.wait_for_timeout(50)


def open_seats(server: Served, trial_id: int, *roles: str) -> None:
    """Each seat's page opened once (its socket joins the trial: a Commander's loads the map)."""
    trial = TrialHandle.on(server, trial_id)

    async def open_each() -> None:
        for role in roles:
            async with trial.seat(role) as seat:
                await seat.wait_for(lambda message: True)

    asyncio.run(open_each())


class Watch(SeatClient):
    """The experimenter's live view, logged in by cookie."""

    def __init__(self, server, trial_id: int, cookie: str | None) -> None:
        super().__init__(server.ws_url, "")
        self.url = f"ws://127.0.0.1:{server.port}/ws/watch/{trial_id}"
        self.cookie = cookie

    async def __aenter__(self) -> Watch:
        headers = {"Cookie": f"{SESSION_COOKIE}={self.cookie}"} if self.cookie else {}
        self.ws = await websockets.connect(self.url, additional_headers=headers, max_size=2**22)
        self._reader = asyncio.get_running_loop().create_task(self._read())
        return self


def cli(*args: str, env: dict[str, str], input: str | None = None) -> subprocess.CompletedProcess:
    """`robotslang ARGS` as a process, with `env` added to this one's environment."""
    return subprocess.run(
        [sys.executable, "-c", "from app.cli import main; main()", *args],
        env={**os.environ, **env},
        cwd=REPO,
        capture_output=True,
        text=True,
        input=input,
        timeout=120,
    )


def add_experimenter(server, name: str = "eve", password: str = PASSWORD) -> None:
    """An experimenter's account in the server's database."""
    with server.services.db.begin() as db:
        db.add(Experimenter(name=name, password_hash=hash_password(password)))


# Scripted players move and speak as fast as the server answers: moves unpaced, a seat's rate far
# above theirs (the tests of floods take the platform's own, `platform_rate`).
UNPACED = {"min_move_interval_s": 0.0, "seat_message_rate_per_s": 1000.0, "seat_message_burst": 1000}
UNPACED_ENV = {f"ROBOTSLANG_{name.upper()}": str(value) for name, value in UNPACED.items()}


def platform_rate() -> dict[str, float]:
    """A seat's rate as the platform ships it (`platform_settings` lifts it for scripted players)."""
    return {name: Settings.model_fields[name].default for name in ("seat_message_rate_per_s", "seat_message_burst")}


def platform_settings(tmp_path, database_url: str | None = None, **overrides) -> Settings:
    """The platform's settings for a test: its data under `tmp_path`, moves as fast as sent."""
    values = dict(
        data_dir=tmp_path / "var",
        database_url=database_url,
        secret_key="test-secret",
        **UNPACED,
        grace_period_s=30.0,
        render_processes=0,  # frames drawn in a thread; tests/app/test_render_processes.py runs the pool
    )
    values.update(overrides)
    return Settings(**values)

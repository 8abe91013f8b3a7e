"""Helpers for the platform's tests: a real uvicorn server on a loopback port (in a thread or a
separate process), trials set up in its database, and seat clients over real websockets."""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import re
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import httpx
import uvicorn
import websockets

from app.db.models import Experimenter
from app.drivers.registry import available_drivers
from app.main import create_app
from app.security import SESSION_COOKIE, hash_password
from app.serving import uvicorn_options
from app.settings import Settings
from app.trial.setup import create_participant, create_team, create_trial

REPO = Path(__file__).resolve().parents[2]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class ServerThread:
    """`create_app(settings)` served by uvicorn on 127.0.0.1 in a background thread."""

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

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    @property
    def ws_url(self) -> str:
        return f"ws://127.0.0.1:{self.port}/ws/play"

    def __enter__(self) -> ServerThread:
        self.thread.start()
        deadline = time.time() + 20
        while not self.server.started:
            if time.time() > deadline or not self.thread.is_alive():
                raise RuntimeError("test server did not start")
            time.sleep(0.02)
        return self

    def __exit__(self, *exc) -> None:
        self.server.should_exit = True
        self.thread.join(timeout=20)
        self.services.engine.dispose()


class ServerProcess:
    """`robotslang serve` as a separate process, so a test can kill it the hard way."""

    def __init__(
        self, env: dict[str, str], port: int | None = None, workers: int = 1, argv: list[str] | None = None
    ) -> None:
        self.env = {**os.environ, **env}
        self.port = port or free_port()
        self.workers = workers
        # `argv`: a command of its own that serves on 127.0.0.1:`port` (a deployment's, say).
        self.argv = argv
        self.proc: subprocess.Popen | None = None

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    @property
    def ws_url(self) -> str:
        return f"ws://127.0.0.1:{self.port}/ws/play"

    def start(self) -> ServerProcess:
        self.proc = subprocess.Popen(
            self.argv
            or [
                sys.executable,
                "-c",
                "from app.cli import main; main()",
                "serve",
                "--port",
                str(self.port),
                "--workers",
                str(self.workers),
            ],
            env=self.env,
            cwd=REPO,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        deadline = time.time() + 30
        while time.time() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"server exited: {self.proc.stdout.read()}")
            try:
                if httpx.get(self.url + "/leaderboard", timeout=1).status_code == 200:
                    return self
            except httpx.HTTPError:
                time.sleep(0.1)
        raise RuntimeError("server did not start in 30 s")

    def kill(self) -> None:
        self.proc.kill()
        self.proc.wait(timeout=10)

    def stop(self) -> None:
        if self.proc and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()


def page_csrf_token(page: str) -> str:
    """The CSRF token a page carries in `<meta name="csrf-token">` (what the page's scripts send)."""
    return re.search(r'<meta name="csrf-token" content="([^"]+)"', page).group(1)


def browser(base_url: str) -> httpx.Client:
    """A client that sends this server's Origin, as a browser does on the server's own pages."""
    return httpx.Client(base_url=base_url, follow_redirects=True, headers={"Origin": base_url})


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


def make_trial(
    services,
    maze: str,
    targets=("mug", "jar", "paddle"),
    driver: str = "human",
    team: str = "Team A",
    backend: str = "sim",
) -> int:
    """A team of two new participants and a trial for it; returns the trial id."""
    with services.db.begin() as db:
        a = create_participant(db, f"{team} commander")
        b = create_participant(db, f"{team} driver")
        t = create_team(db, team, a.id, b.id)
        trial = create_trial(
            db,
            team_id=t.id,
            maze=maze,
            targets=list(targets),
            backend=backend,
            driver=driver,
            commander_id=a.id,
            maze_names=services.mazes.names(),
            now_ns=services.clock.now_ns(),
            agents=available_drivers(services),
        )
        return trial.id


class SeatClient:
    """One seat over a real websocket: every message received is kept, in order."""

    def __init__(self, ws_url: str, token: str, origin: str | None = None) -> None:
        self.url, self.token, self.origin = f"{ws_url}?token={token}", token, origin
        self.received: list[dict[str, Any]] = []
        self._new = asyncio.Event()
        self.ws = None

    async def __aenter__(self) -> SeatClient:
        self.ws = await websockets.connect(self.url, origin=self.origin, max_size=2**22)
        self._reader = asyncio.get_running_loop().create_task(self._read())
        return self

    async def __aexit__(self, *exc) -> None:
        await self.ws.close()
        self._reader.cancel()

    async def _read(self) -> None:
        try:
            async for raw in self.ws:
                self.received.append(json.loads(raw))
                self._new.set()
        except websockets.ConnectionClosed:
            pass

    async def send(self, type: str, token: str | None = None, **fields) -> None:
        await self.ws.send(json.dumps({"type": type, "token": token or self.token, **fields}))

    async def wait_for(self, predicate, timeout: float = 10.0, start: int = 0) -> dict[str, Any]:
        """The first message from index `start` on that satisfies `predicate`."""
        deadline = asyncio.get_running_loop().time() + timeout
        i = start
        while True:
            while i < len(self.received):
                if predicate(self.received[i]):
                    return self.received[i]
                i += 1
            remaining = deadline - asyncio.get_running_loop().time()
            if remaining <= 0:
                kinds = [m.get("kind", m.get("type")) for m in self.received[-15:]]
                raise AssertionError(f"no matching message in {timeout} s; last received: {kinds}")
            self._new.clear()
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._new.wait(), remaining)

    async def event(self, kind: str, timeout: float = 10.0, start: int = 0, **match) -> dict[str, Any]:
        return await self.wait_for(
            lambda m: m.get("type") == "event"
            and m["kind"] == kind
            and all(m["payload"].get(k) == v for k, v in match.items()),
            timeout,
            start,
        )

    def kinds(self) -> set[str]:
        return {m["kind"] for m in self.received if m.get("type") == "event"}


def wait_js(page, expression: str, timeout_s: float = 30.0) -> None:
    """Poll a JavaScript expression (or `() => ...` function) in `page` until it is truthy.
    Playwright's own wait_for_function polls through eval, which the pages' CSP rightly forbids."""
    deadline = time.monotonic() + timeout_s
    while not page.evaluate(expression):
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s} s waiting for {expression!r}")
        page.wait_for_timeout(50)

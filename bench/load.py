"""Load on loopback: N concurrent simulator trials, each with a scripted Commander and Driver
over websockets sending a chat message and a move every second.

How the Driver moves (`--pattern`): `random` draws forward, forward, left or right at each move,
so it mostly turns about and shuffles near where it started, and most frames are of poses drawn
before; `walk` drives forward until a bump and then turns, as a person or an agent explores, so nearly
every move is a new pose and a new render. `--mazes distinct` puts every trial on a maze of its
own, drawn from the bundled and the benchmark's mazes (`--benchmark`), with generated ones added
when there are not enough; `--mazes shared` (the default) puts them on the bundled mazes in turn. Seats open at most `OPEN_AT_ONCE` handshakes at a time, or all at
once (`--open-at-once`, each handshake given `HANDSHAKE_TIMEOUT_S`, as a crowd arriving together).

Prints p50/p99 of chat fan-out latency (Commander sends -> Driver receives), of move-to-frame
latency (Driver sends a move -> receives the new camera frame) over the measured window, and of
each trial's first move apart (its maze's first frame after the seat joined), the handshake times
(socket opened -> upgrade answered: the server opens the trial before it answers), events
committed per second, lost chat messages (sent, never heard by the Driver) and unanswered moves
(neither a frame nor a refusal came back), the server's CPU (cores busy) and peak RSS, all
processes together and each process (the server, its workers, its render processes), how many
of the watched trials had a particle filter's belief at the end (`beliefs`: the server runs a
trial's filter only while an experimenter watches it; `--watchers N` watches the first N, one by
default, as a lab's experimenter watches a trial), the CPU of the bench's own seats (`client_cpu`: on a small machine they compete with the server for its
cores) and the machine's load average before the run and at its end. The server runs as its own
process (`robotslang serve --workers W`), as in use: one process on SQLite (WAL); with W > 1 the
processes share trials through Redis (`--redis-url`) and PostgreSQL (a private schema in
`--postgres-url`, dropped afterwards). The trials, each with its two participants and team, are
created once the server is up, over HTTP with the experimenter's forms, and each answer is timed
(trial creation p50/p95, participants' and teams' p95). What trials need of the mazes (graphs,
ray tables, render scenes) is prepared before the server starts, as on a machine that has run
each maze once (it is cached on disk), unless `--fresh-caches`: then the run has an empty cache
directory of its own, as a fresh install, and the server prepares the mazes from its start.

    python -m bench.load --trials 50 --workers 1 --duration 30 [--json]
    python -m bench.load --trials 200 --pattern walk --mazes distinct --open-at-once [--fresh-caches]
    python -m bench.load --find-max [--max-trials 400] [--duration 10]   # largest N with both p99 < 100 ms
    python -m bench.load --trials 100 --profile var/load.svg              # py-spy flame graph of the server
    python -m bench.load --trials 200 --agent-drivers 50 --duration 20    # 50 of them with agent:dialog driving

With `--agent-drivers N`, N of the trials seat `agent:dialog` in the Driver's seat (it runs in the
server); the bench's seat there is the Commander alone, who speaks `AGENT_INSTRUCTIONS` in turn at
the same pace (the next once the agent has replied, or after `REPLY_WAIT_S`). Their chat latency is
the Commander's message coming back to the Commander (the same fan-out a Driver's page gets) and
counts in the chat figures over all trials; apart, it prints the agents' replies (Commander's
message -> the agent's next words) and the moves they made.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import gc
import json
import os
import random
import re
import subprocess
import sys
import tempfile
import time
import uuid
from collections import deque
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from enum import StrEnum
from pathlib import Path

import httpx
import websockets
from rich.console import Console
from rich.progress import Progress
from sqlalchemy import create_engine, func, select, text

from app.db.models import Event, Experimenter, Participant, Team, Trial
from app.main import build_services
from app.security import SESSION_COOKIE, hash_password
from app.settings import Settings
from bench.live import ServerProcess, ServerProcesses, settings_env
from bench.report import percentile
from sim.core.cache import cache_dir

console = Console(stderr=True)
P99_GOAL_MS = 100.0
READY_WAIT_S = 180.0  # at most this long for every trial's seats to connect before the warm-up
DRAIN_S = 3.0  # after the run: how long late answers may still arrive before they count as lost
OPEN_AT_ONCE = 20  # handshakes in flight at a time, unless --open-at-once
HANDSHAKE_TIMEOUT_S = 10.0  # with --open-at-once, as a browser's patience
CONNECTED_GOAL_S = 5.0  # every seat opening at once connected within this
GENERATED_SEED = 10_000  # seeds of the mazes generated when the library has too few
AGENT_DRIVER = "agent:dialog"
AGENT_INSTRUCTIONS = ("what do you see?", "turn left", "go forward 3 steps", "turn right", "what is on your left?")
REPLY_WAIT_S = 5.0  # an agent's reply not come by then: counted unreplied, and the Commander speaks again
LOAD_EXPERIMENTER = ("load", "the load bench's experimenter")  # name, password: who creates the trials


class Pattern(StrEnum):
    RANDOM = "random"  # forward, forward, left or right, drawn at each move
    WALK = "walk"  # forward until a bump, then a turn


class MazeChoice(StrEnum):
    SHARED = "shared"  # the bundled mazes, in turn
    DISTINCT = "distinct"  # every trial on a maze of its own


def distinct_mazes(n: int, benchmark: Path | None, tmp: Path) -> Path | None:
    """A benchmark folder whose library holds at least `n` mazes: `benchmark` itself, or (when it
    and the bundled mazes are too few) a folder in `tmp` linking its runs and mazes generated once
    into the cache (deterministic seeds, reused by later runs)."""
    from sim.tasks.generator import generate_maze
    from sim.tasks.library import MazeLibrary

    have = len(MazeLibrary(benchmark=benchmark, cache=False))
    if have >= n:
        return benchmark
    mazedata = tmp / "mazes" / "mazedata"
    mazedata.mkdir(parents=True)
    if benchmark is not None:
        for run in (benchmark / "mazedata").iterdir():
            (mazedata / run.name).symlink_to(run)
    generated = cache_dir() / "bench-load-mazes"
    for i in range(n - have):
        name = f"load-{i:03d}"
        if not (generated / name / "maze").is_dir():
            console.print(f"generating maze {name} (once: it is kept in {generated})")
            generate_maze(GENERATED_SEED + i, name=name).save(generated / name)
        (mazedata / name).symlink_to(generated / name)
    return mazedata.parent


def setup_services(
    settings: Settings, n: int, mazes: MazeChoice, fresh_caches: bool
) -> tuple[object, list[str], list[str]]:
    """The bench's own handle on the server's database (the seats' tokens, the watchers, the
    events counted), its experimenter `LOAD_EXPERIMENTER`, and the maze of each of the `n` trials
    (and the library's names). Unless `fresh_caches`, what trials need of those mazes is prepared
    before the server starts, as on a machine that has run each maze once."""
    from app.preparation import prepare_maze

    services = build_services(settings)
    maze_names = services.mazes.names()
    if mazes == MazeChoice.SHARED:
        maze_names = [name for name in maze_names if services.mazes.library.source(name) == "bundled"]
    elif len(maze_names) < n:
        raise SystemExit(f"{n} trials on distinct mazes need {n} mazes; the library holds {len(maze_names)}")
    chosen = [maze_names[i % len(maze_names)] for i in range(n)]
    with services.db.begin() as db:
        db.add(Experimenter(name=LOAD_EXPERIMENTER[0], password_hash=hash_password(LOAD_EXPERIMENTER[1])))
    if not fresh_caches:
        with Progress(console=console, transient=True) as progress:
            for name in progress.track(sorted(set(chosen)), description="preparing the mazes (cached on disk)"):
                prepare_maze(services.mazes.library, name, settings.cache_dir)
    return services, chosen, maze_names


@dataclass
class Creation:
    """How long the experimenter's requests that set up the trials took to answer, ms."""

    participant_ms: list[float] = field(default_factory=list)
    team_ms: list[float] = field(default_factory=list)
    trial_ms: list[float] = field(default_factory=list)


def create_trials(
    url: str, services, chosen: list[str], agent_drivers: int = 0
) -> tuple[list[tuple[str, str | None]], Creation]:
    """A trial on each of `chosen`, with its two participants and team, created as the experimenter
    does it, over HTTP with the dashboard's forms (each answer timed, the dashboard it redirects to
    not fetched); the seats' tokens (no Driver's for the first `agent_drivers`, whose Driver is
    `AGENT_DRIVER`)."""
    creation, tokens = Creation(), []
    with httpx.Client(base_url=url, headers={"Origin": url}, timeout=120) as client:
        login = re.search(r'name="csrf_token" value="([^"]+)"', client.get("/").text)
        name, password = LOAD_EXPERIMENTER
        client.post("/login", data={"name": name, "password": password, "csrf_token": login.group(1)})
        page = client.get("/experimenter/replays")
        client.headers["X-CSRF-Token"] = re.search(r'<meta name="csrf-token" content="([^"]+)"', page.text).group(1)

        def post(path: str, times: list[float], **form) -> None:
            started = time.perf_counter()
            answer = client.post(path, data=form)
            times.append(1e3 * (time.perf_counter() - started))
            refused = "error=" in answer.headers.get("location", "")
            if answer.status_code != 303 or refused:
                raise SystemExit(f"POST {path} {form}: {answer.status_code} {answer.headers.get('location', '')}")

        for i, maze in progress_over(chosen, "creating trials over HTTP"):
            people = [f"load-{i} commander", f"load-{i} driver"]
            for person in people:
                post("/experimenter/participants", creation.participant_ms, name=person)
            with services.db() as db:
                a, b = (db.scalar(select(Participant.id).where(Participant.name == p)) for p in people)
            team = f"load-team-{i}"
            post("/experimenter/teams", creation.team_ms, name=team, member_a=a, member_b=b)
            with services.db() as db:
                team_id = db.scalar(select(Team.id).where(Team.name == team))
            agent = i < agent_drivers
            driver = AGENT_DRIVER if agent else "human"
            post(
                "/experimenter/trials",
                creation.trial_ms,
                team_id=team_id,
                maze=maze,
                targets="mug,jar,paddle",
                driver=driver,
            )
            with services.db() as db:
                trial_id = db.scalar(select(Trial.id).where(Trial.team_id == team_id))
            tokens.append(
                (
                    services.seats.issue(trial_id, "commander"),
                    None if agent else services.seats.issue(trial_id, "driver"),
                )
            )
    return tokens, creation


def progress_over(items: list[str], description: str):
    with Progress(console=console, transient=True) as progress:
        yield from enumerate(progress.track(items, description=description))


@dataclass
class Figures:
    chat_ms: list[float] = field(default_factory=list)
    frame_ms: list[float] = field(default_factory=list)  # moves sent in the window but each trial's first
    first_ms: list[float] = field(default_factory=list)  # each trial's first move, when it came
    handshake_ms: list[float] = field(default_factory=list)  # every seat's that was answered
    welcome_ms: list[float] = field(default_factory=list)  # socket opened -> the seat's welcome
    handshakes_failed: int = 0
    chats_sent: int = 0
    chats_heard: int = 0
    moves_sent: int = 0
    moves_answered: int = 0
    ready: int = 0  # trials whose two seats are connected and welcomed
    agent_reply_ms: list[float] = field(default_factory=list)  # Commander's words -> the agent's next
    agent_unreplied: int = 0
    agent_moves: int = 0
    agent_chat_ms: list[float] = field(default_factory=list)
    recording: bool = False


async def open_seat(url: str, figures: Figures, gate: asyncio.Semaphore | None, timeout: float):
    """The seat's socket once welcomed, its handshake and its welcome timed (a failed one counted)."""
    async with gate or contextlib.nullcontext():
        t0 = time.perf_counter()
        try:
            ws = await websockets.connect(url, max_size=2**22, open_timeout=timeout)
        except (OSError, TimeoutError, websockets.InvalidHandshake):
            figures.handshakes_failed += 1
            raise
        figures.handshake_ms.append((time.perf_counter() - t0) * 1e3)
        while json.loads(await ws.recv())["type"] != "welcome":  # its own joining may come first
            pass
        figures.welcome_ms.append((time.perf_counter() - t0) * 1e3)
        return ws


async def run_trial(
    ws_url: str,
    tokens: tuple[str, str],
    pattern: Pattern,
    gate: asyncio.Semaphore | None,
    figures: Figures,
    stop: asyncio.Event,
    drained: asyncio.Event,
) -> None:
    commander_token, driver_token = tokens
    timeout = 60.0 if gate else HANDSHAKE_TIMEOUT_S
    if driver_token is None:
        await run_agent_trial(ws_url, commander_token, gate, figures, stop, drained)
        return
    seats = await asyncio.gather(
        open_seat(f"{ws_url}?token={commander_token}", figures, gate, timeout),
        open_seat(f"{ws_url}?token={driver_token}", figures, gate, timeout),
        return_exceptions=True,
    )
    if any(isinstance(seat, BaseException) for seat in seats):
        for seat in seats:
            if not isinstance(seat, BaseException):
                await seat.close()
        raise next(seat for seat in seats if isinstance(seat, BaseException))
    async with seats[0] as commander, seats[1] as driver:
        chats: dict[str, tuple[float, bool]] = {}  # text -> (sent at, sent while recording)
        move: list = []  # [sent at, counted, first] of the move waiting for its frame
        bumped = [False]  # the last forward move collided: turn

        async def driver_reader():
            async for raw in driver:
                now = time.perf_counter()
                message = json.loads(raw)
                kind = message.get("kind") if message.get("type") == "event" else message.get("type")
                if kind == "chat" and message["payload"]["text"] in chats:
                    sent, counted = chats.pop(message["payload"]["text"])
                    if counted:
                        figures.chats_heard += 1
                        if figures.recording:
                            figures.chat_ms.append((now - sent) * 1e3)
                outcome = message["payload"]["outcome"] if kind == "move_executed" else None
                bumped[0] = bumped[0] if outcome is None else outcome == "collision"
                refused = kind in ("error", "move_refused") or outcome == "refused"
                if move and (kind == "frame" or refused):
                    sent, counted, first = move
                    move.clear()
                    if first and kind == "frame":
                        figures.first_ms.append((now - sent) * 1e3)
                    if counted:
                        figures.moves_answered += 1
                        if kind == "frame" and figures.recording and not first:
                            figures.frame_ms.append((now - sent) * 1e3)

        async def commander_reader():
            async for _ in commander:  # the Commander hears its own echo; nothing to measure
                pass

        readers = [asyncio.create_task(driver_reader()), asyncio.create_task(commander_reader())]
        figures.ready += 1
        rng = random.Random()
        turn = rng.choice(["left", "right"])  # the walk's way round at a bump
        loop = asyncio.get_running_loop()
        # Each trial keeps its own phase in the second, on absolute deadlines: with sleeps measured
        # from the last send, every stall of this process lined up the trials' phases, and a minute
        # in, the offered load came in bursts several times the mean (20 ms bins: CV 0.6 -> 1.5).
        start = loop.time() + rng.random()
        await asyncio.sleep(start - loop.time())
        await commander.send(json.dumps({"type": "localize", "token": commander_token, "x": 1.2, "y": 1.0}))
        i = 0
        while not stop.is_set():
            text = f"where are you now? {id(chats)}-{i}"
            chats[text] = (time.perf_counter(), figures.recording)
            figures.chats_sent += figures.recording
            await commander.send(json.dumps({"type": "chat", "token": commander_token, "text": text}))
            await asyncio.sleep(start + i + 0.5 - loop.time())
            if not move:  # one move at a time, as the Driver's page does
                move[:] = [time.perf_counter(), figures.recording, i == 0]
                figures.moves_sent += figures.recording
                if pattern == Pattern.WALK:
                    action = turn if bumped[0] else "forward"
                else:
                    action = rng.choice(["forward", "forward", "left", "right"])
                await driver.send(json.dumps({"type": "move", "token": driver_token, "action": action}))
            i += 1
            await asyncio.sleep(start + i - loop.time())
        await drained.wait()
        for task in readers:
            task.cancel()


async def run_agent_trial(
    ws_url: str,
    commander_token: str,
    gate: asyncio.Semaphore | None,
    figures: Figures,
    stop: asyncio.Event,
    drained: asyncio.Event,
) -> None:
    """The Commander of a trial whose Driver is an agent: an instruction a second at most, the next
    once the agent has replied (or after `REPLY_WAIT_S`)."""
    timeout = 60.0 if gate else HANDSHAKE_TIMEOUT_S
    async with await open_seat(f"{ws_url}?token={commander_token}", figures, gate, timeout) as commander:
        echoes: deque[tuple[str, float, bool]] = deque()  # the Commander's words not heard back yet
        asked: list[tuple[float, bool]] = []  # when the last words went out, until the agent replies

        async def reader():
            async for raw in commander:
                now = time.perf_counter()
                message = json.loads(raw)
                if message.get("type") != "event":
                    continue
                kind, payload = message["kind"], message["payload"]
                if kind == "chat" and payload["role"] == "commander" and echoes and echoes[0][0] == payload["text"]:
                    _, sent, counted = echoes.popleft()
                    if counted:
                        figures.chats_heard += 1
                        if figures.recording:
                            figures.chat_ms.append((now - sent) * 1e3)
                            figures.agent_chat_ms.append((now - sent) * 1e3)
                elif kind == "chat" and payload["role"] == "driver" and asked:
                    sent, counted = asked.pop()
                    if counted and figures.recording:
                        figures.agent_reply_ms.append((now - sent) * 1e3)

        task = asyncio.create_task(reader())
        figures.ready += 1
        loop = asyncio.get_running_loop()
        start = loop.time() + random.random()
        await asyncio.sleep(start - loop.time())
        await commander.send(json.dumps({"type": "localize", "token": commander_token, "x": 1.2, "y": 1.0}))
        i = said = 0
        while not stop.is_set():
            waited = asked and time.perf_counter() - asked[0][0] > REPLY_WAIT_S
            if waited and asked.pop()[1]:
                figures.agent_unreplied += 1
            if not asked:
                text = AGENT_INSTRUCTIONS[said % len(AGENT_INSTRUCTIONS)]
                said += 1
                sent = (time.perf_counter(), figures.recording)
                echoes.append((text, *sent))
                asked.append(sent)
                figures.chats_sent += figures.recording
                await commander.send(json.dumps({"type": "chat", "token": commander_token, "text": text}))
            i += 1
            await asyncio.sleep(start + i - loop.time())
        await drained.wait()
        task.cancel()


async def drive(
    ws_url: str,
    tokens,
    pattern: Pattern,
    open_at_once: bool,
    warmup: float,
    duration: float,
    services,
    server: ServerProcesses,
    watched: list[int],
) -> tuple[Figures, int, float, float, float, int]:
    figures, stop, drained = Figures(), asyncio.Event(), asyncio.Event()
    gate = None if open_at_once else asyncio.Semaphore(OPEN_AT_ONCE)
    tasks = [asyncio.create_task(run_trial(ws_url, t, pattern, gate, figures, stop, drained)) for t in tokens]
    with Progress(console=console, transient=True) as progress:  # opening hundreds of trials takes a while
        bar = progress.add_task("seats connecting", total=len(tokens))
        for _ in range(int(READY_WAIT_S / 0.2)):
            progress.update(bar, completed=figures.ready)
            server.sample_rss()
            if figures.ready == len(tokens) or all(t.done() for t in tasks):
                break
            await asyncio.sleep(0.2)
    failed = [t.exception() for t in tasks if t.done() and t.exception() is not None]
    if failed and not open_at_once:  # all at once, the handshakes that failed are a figure
        raise SystemExit(f"{len(failed)} trials could not connect: {failed[0]!r}")
    watching = [asyncio.create_task(watch(ws_url, trial_id, services)) for trial_id in watched]
    # The seats' own collector: 400 sockets' objects made its full passes stop this loop 110-175 ms,
    # and every message in flight then was counted as the server's latency. What the seats built
    # to connect is theirs for the whole run; its passes now walk only what comes after.
    gc.collect()
    gc.freeze()
    await asyncio.sleep(warmup)

    def count() -> int:
        with services.db() as db:  # closed: an open transaction would block dropping the schema
            return db.execute(select(func.count(Event.id))).scalar_one()

    def agent_moves() -> int:  # the Commander's page does not show moves: the log does
        moves = select(func.count(Event.id)).join(Trial, Trial.id == Event.trial_id)
        moves = moves.where(Trial.driver == AGENT_DRIVER, Event.kind == "move_executed")
        with services.db() as db:
            return db.execute(moves).scalar_one()

    before, moved = count(), agent_moves()
    t0, cpu0, own0 = time.perf_counter(), server.cpu_s(), time.process_time()
    figures.recording = True
    with Progress(console=console, transient=True) as progress:
        bar = progress.add_task(f"{len(tokens)} trials under load", total=duration)
        while (elapsed := time.perf_counter() - t0) < duration:
            await asyncio.sleep(0.5)
            server.sample_rss()
            progress.update(bar, completed=min(elapsed, duration))
    figures.recording = False
    committed, window = count() - before, time.perf_counter() - t0
    figures.agent_moves = agent_moves() - moved
    cpu = (server.cpu_s() - cpu0) / window
    # The seats' own side: on a small machine the clients compete with the server for its cores.
    client_cpu = (time.process_time() - own0) / window
    beliefs = await asyncio.to_thread(
        beliefs_shown, ws_url.replace("ws://", "http://").removesuffix("/ws/play"), services
    )
    stop.set()
    await asyncio.sleep(DRAIN_S)
    drained.set()
    for task in watching:
        task.cancel()
    await asyncio.gather(*tasks, *watching, return_exceptions=True)
    return figures, committed, window, cpu, client_cpu, beliefs


def first_trials(services, n: int) -> list[int]:
    with services.db() as db:
        return list(db.scalars(select(Trial.id).order_by(Trial.id).limit(n)))


async def watch(ws_url: str, trial_id: int, services) -> None:
    """The experimenter's live view of one trial, as the watch page holds it: the server runs a
    trial's particle filter only while someone watches it."""
    cookie = f"{SESSION_COOKIE}={services.sessions.issue(first_experimenter(services))}"
    url = ws_url.removesuffix("/ws/play") + f"/ws/watch/{trial_id}"
    async with websockets.connect(url, additional_headers={"Cookie": cookie}, max_size=2**22) as ws:
        async for _ in ws:
            pass


def first_experimenter(services) -> int:
    with services.db() as db:
        experimenter = db.scalar(select(Experimenter.id).order_by(Experimenter.id).limit(1))
    if experimenter is None:
        raise SystemExit("the server made no experimenter account at its first start")
    return experimenter


def beliefs_shown(http_url: str, services) -> int:
    """Live trials with a particle filter's belief, as the experimenter's `/experimenter/api/trials`
    gives them (every process's trials: with Redis each publishes its own). The peak memory counts
    the filters only once they are built, in the filters' share of a core: all of them by the end,
    or the run was too short to say what they cost."""
    cookies = {SESSION_COOKIE: services.sessions.issue(first_experimenter(services))}
    trials = httpx.get(f"{http_url}/experimenter/api/trials", cookies=cookies, timeout=60).json()["trials"]
    return sum(t["belief"] is not None for t in trials)


@contextmanager
def database(workers: int, postgres_url: str):
    """None (the embedded SQLite file) for one process; a private PostgreSQL schema for several."""
    if workers == 1:
        yield None
        return
    schema = f"load_{uuid.uuid4().hex[:12]}"
    admin = create_engine(postgres_url)
    with admin.begin() as conn:
        conn.execute(text(f"create schema {schema}"))
    try:
        yield f"{postgres_url}?options=-csearch_path%3D{schema}"
    finally:
        with admin.begin() as conn:
            conn.execute(text(f"drop schema {schema} cascade"))
        admin.dispose()


@dataclass(frozen=True)
class Load:
    """What one run offers the server."""

    trials: int
    workers: int = 1
    pattern: Pattern = Pattern.RANDOM
    mazes: MazeChoice = MazeChoice.SHARED
    open_at_once: bool = False
    benchmark: Path | None = None
    agent_drivers: int = 0  # of `trials`, seating AGENT_DRIVER in the Driver's seat
    watchers: int = 1  # the experimenter's live views, on the first trials: their particle filters run
    fresh_caches: bool = False  # an empty cache directory of its own, as a fresh install's


def run_load(
    load: Load,
    duration: float,
    warmup: float,
    port: int,
    redis_url: str | None,
    postgres_url: str,
    profile: str | None = None,
) -> dict:
    """One run: a fresh data directory, database and server, `load.trials` trials; returns the figures."""
    trials, workers = load.trials, load.workers
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="robotslang-load-") as tmp, database(workers, postgres_url) as url:
        benchmark = None
        if load.mazes == MazeChoice.DISTINCT:
            benchmark = distinct_mazes(trials, load.benchmark, Path(tmp))
        cache = Path(tmp) / "cache" if load.fresh_caches else cache_dir()
        settings = Settings(
            data_dir=Path(tmp) / "var", secret_key="load", database_url=url, benchmark=benchmark, cache_dir=cache
        )
        services, chosen, maze_names = setup_services(settings, trials, load.mazes, load.fresh_caches)
        # Redis only for several processes, whatever this shell's environment names.
        env = {**settings_env(settings), "ROBOTSLANG_REDIS_URL": redis_url if workers > 1 else None}
        server = ServerProcess(env, port, workers)
        spy = None
        try:
            server.start()
            processes = ServerProcesses(server.proc.pid, workers)
            tokens, creation = create_trials(server.url, services, chosen, load.agent_drivers)
            if profile:  # the whole run, warm-up included, sampled from every server process
                spy = subprocess.Popen(
                    [
                        str(Path(sys.executable).with_name("py-spy")),
                        "record",
                        "--subprocesses",
                        "--idle",
                        "--rate",
                        "100",
                        "--format",
                        "speedscope" if profile.endswith(".json") else "flamegraph",
                        "-o",
                        profile,
                        "--pid",
                        str(server.proc.pid),
                    ],
                    stdout=subprocess.DEVNULL,
                    stderr=subprocess.DEVNULL,
                )
            figures, committed, window, cpu, client_cpu, beliefs = asyncio.run(
                drive(
                    server.ws_url,
                    tokens,
                    load.pattern,
                    load.open_at_once,
                    warmup,
                    duration,
                    services,
                    processes,
                    first_trials(services, load.watchers),
                )
            )
        finally:
            if spy is not None:
                spy.send_signal(2)
                spy.wait(timeout=60)
            server.stop()
            services.engine.dispose()
    handshakes = figures.handshake_ms
    return {
        "trials": trials,
        "workers": workers,
        "pattern": str(load.pattern),
        "mazes": str(load.mazes),
        "maze_count": len(set(chosen)),
        "fresh_caches": load.fresh_caches,
        "create_trial_p50_ms": round(percentile(creation.trial_ms, 50), 2),
        "create_trial_p95_ms": round(percentile(creation.trial_ms, 95), 2),
        "create_trial_max_ms": round(max(creation.trial_ms), 2),
        "create_participant_p95_ms": round(percentile(creation.participant_ms, 95), 2),
        "create_team_p95_ms": round(percentile(creation.team_ms, 95), 2),
        "open_at_once": load.open_at_once,
        "duration_s": round(window, 1),
        "chat_p50_ms": round(percentile(figures.chat_ms, 50), 2),
        "chat_p99_ms": round(percentile(figures.chat_ms, 99), 2),
        "move_to_frame_p50_ms": round(percentile(figures.frame_ms, 50), 2),
        "move_to_frame_p99_ms": round(percentile(figures.frame_ms, 99), 2),
        "first_move_p50_ms": round(percentile(figures.first_ms, 50), 2),
        "first_move_p99_ms": round(percentile(figures.first_ms, 99), 2),
        "first_moves": len(figures.first_ms),
        "handshake_p50_ms": round(percentile(handshakes, 50), 2),
        "handshake_p99_ms": round(percentile(handshakes, 99), 2),
        "handshake_max_ms": round(max(handshakes, default=float("nan")), 2),
        "handshakes": len(handshakes),
        "handshakes_failed": figures.handshakes_failed,
        "welcome_p50_ms": round(percentile(figures.welcome_ms, 50), 2),
        "welcome_p99_ms": round(percentile(figures.welcome_ms, 99), 2),
        "welcome_max_ms": round(max(figures.welcome_ms, default=float("nan")), 2),
        "connected_within_goal": sum(ms <= CONNECTED_GOAL_S * 1e3 for ms in handshakes),
        "chats": len(figures.chat_ms),
        "moves": len(figures.frame_ms),
        "events_per_s": round(committed / window, 1),
        "events": committed,
        "lost": figures.chats_sent - figures.chats_heard,
        "unanswered": figures.moves_sent - figures.moves_answered,
        "agent_drivers": load.agent_drivers,
        "agent_reply_p50_ms": round(percentile(figures.agent_reply_ms, 50), 2),
        "agent_reply_p95_ms": round(percentile(figures.agent_reply_ms, 95), 2),
        "agent_replies": len(figures.agent_reply_ms),
        "agent_unreplied": figures.agent_unreplied,
        "agent_moves": figures.agent_moves,
        "agent_chat_p99_ms": round(percentile(figures.agent_chat_ms, 99), 2),
        "server_cpu": round(cpu, 2),
        "client_cpu": round(client_cpu, 2),
        "server_rss_mb": round(processes.peak_rss_mb, 1),
        "beliefs": beliefs,
        "watchers": load.watchers,
        "processes": processes.peaks(),
        "load_average_before": [round(x, 2) for x in load_before],
        "load_average": [round(x, 2) for x in os.getloadavg()],
    }


def within_goal(figures: dict) -> bool:
    return (
        figures["chat_p99_ms"] < P99_GOAL_MS
        and figures["move_to_frame_p99_ms"] < P99_GOAL_MS
        and figures["lost"] == 0
        and figures["unanswered"] == 0
        and figures["handshakes_failed"] == 0
    )


def find_max(load: Load, args) -> tuple[int, list[dict]]:
    """The largest trial count (a multiple of `--step`, at most `--max-trials`) with both p99s under
    100 ms and nothing lost: doubling from `--step`, then bisection; at most `--max-probes` runs."""
    runs: list[dict] = []

    def ok(n: int) -> bool:
        figures = run_load(
            replace(load, trials=n), args.duration, args.warmup, args.port, args.redis_url, args.postgres_url
        )
        runs.append(figures)
        report(figures)
        return within_goal(figures)

    good, bad, n = 0, None, args.step
    while n <= args.max_trials and len(runs) < args.max_probes:
        if not ok(n):
            bad = n
            break
        good, n = n, min(2 * n, args.max_trials) if n < args.max_trials else args.max_trials + 1
    hi = bad if bad is not None else good
    while bad is not None and hi - good > args.step and len(runs) < args.max_probes:
        mid = (good + hi) // 2 // args.step * args.step
        if ok(mid):
            good = mid
        else:
            hi = mid
    return good, runs


def report(f: dict) -> None:
    before, after = (", ".join(f"{x:.2f}" for x in f[key]) for key in ("load_average_before", "load_average"))
    console.print(
        f"[bold]bench.load[/]: {f['trials']} trials on {f['maze_count']} mazes ({f['mazes']}), pattern "
        f"{f['pattern']}, {f['workers']} server process(es), 1 chat + 1 move per second each, "
        f"{f['duration_s']:.0f} s measured ({os.cpu_count()} CPUs, "
        f"{'SQLite WAL' if f['workers'] == 1 else 'PostgreSQL + Redis'}; load average {before} before, {after} at the end)"
    )
    console.print(
        f"  trial creation  p50 {f['create_trial_p50_ms']:7.1f} ms   p95 {f['create_trial_p95_ms']:7.1f} ms   "
        f"max {f['create_trial_max_ms']:.0f} ms   (over HTTP, {f['trials']} trials; each's participants p95 "
        f"{f['create_participant_p95_ms']:.1f} ms, team p95 {f['create_team_p95_ms']:.1f} ms; "
        f"{'fresh caches' if f['fresh_caches'] else 'mazes prepared before the start'})"
    )
    opened = "all at once" if f["open_at_once"] else f"{OPEN_AT_ONCE} at a time"
    console.print(
        f"  handshakes      p50 {f['handshake_p50_ms']:7.1f} ms   p99 {f['handshake_p99_ms']:7.1f} ms   "
        f"max {f['handshake_max_ms']:.0f} ms   ({f['handshakes']} answered, opened {opened}; "
        f"{f['connected_within_goal']} within {CONNECTED_GOAL_S:.0f} s, {f['handshakes_failed']} failed)"
    )
    console.print(
        f"  welcome         p50 {f['welcome_p50_ms']:7.1f} ms   p99 {f['welcome_p99_ms']:7.1f} ms   "
        f"max {f['welcome_max_ms']:.0f} ms   (socket opened -> the seat's welcome)"
    )
    console.print(
        f"  first move      p50 {f['first_move_p50_ms']:7.1f} ms   p99 {f['first_move_p99_ms']:7.1f} ms   "
        f"({f['first_moves']} trials' first move to its frame)"
    )
    console.print(
        f"  chat fan-out    p50 {f['chat_p50_ms']:7.1f} ms   p99 {f['chat_p99_ms']:7.1f} ms   "
        f"({f['chats']} messages, {f['lost']} lost)"
    )
    console.print(
        f"  move-to-frame   p50 {f['move_to_frame_p50_ms']:7.1f} ms   "
        f"p99 {f['move_to_frame_p99_ms']:7.1f} ms   ({f['moves']} moves, {f['unanswered']} unanswered)"
    )
    if f["agent_drivers"]:
        console.print(
            f"  agent Drivers   {f['agent_drivers']} trials ({AGENT_DRIVER}): replies p50 "
            f"{f['agent_reply_p50_ms']:7.1f} ms   p95 {f['agent_reply_p95_ms']:7.1f} ms   ({f['agent_replies']} "
            f"replies, {f['agent_unreplied']} unreplied in {REPLY_WAIT_S:.0f} s), {f['agent_moves']} moves; "
            f"their chat p99 {f['agent_chat_p99_ms']:.1f} ms (in the chat figures above)"
        )
    console.print(
        f"  events committed {f['events_per_s']:7.1f} /s   server CPU {f['server_cpu']:.2f} cores   "
        f"(the bench's seats {f['client_cpu']:.2f})   peak RSS {f['server_rss_mb']:.0f} MB all together"
    )
    for p in f["processes"]:
        console.print(f"    {p['kind']:<8} pid {p['pid']:<8} peak RSS {p['peak_rss_mb']:7.0f} MB")
    console.print(f"  particle filters with a belief at the end: {f['beliefs']} of the {f['watchers']} watched trials")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--trials", type=int, default=50)
    parser.add_argument("--pattern", type=Pattern, choices=list(Pattern), default=Pattern.RANDOM)
    parser.add_argument("--mazes", type=MazeChoice, choices=list(MazeChoice), default=MazeChoice.SHARED)
    parser.add_argument(
        "--benchmark",
        type=Path,
        default=os.environ.get("ROBOTSLANG_BENCHMARK"),
        help="with --mazes distinct: the benchmark whose mazes join the bundled ones (ROBOTSLANG_BENCHMARK)",
    )
    parser.add_argument("--open-at-once", action="store_true", help="every seat's socket opened at the same time")
    parser.add_argument(
        "--fresh-caches",
        action="store_true",
        help="an empty cache directory (and data directory) for the run, as on a fresh install: the server "
        "prepares the mazes from its start, and nothing is prepared before",
    )
    parser.add_argument(
        "--agent-drivers", type=int, default=0, help=f"of the trials, how many seat {AGENT_DRIVER} as the Driver"
    )
    parser.add_argument(
        "--workers", type=int, help="server processes (over 1: needs Redis); default 1, with --find-max 1 and 2"
    )
    parser.add_argument(
        "--watchers",
        type=int,
        default=1,
        help="experimenter live views opened on the first trials, as a lab watches one (their particle filters run)",
    )
    parser.add_argument("--duration", type=float, default=30.0, help="measured seconds")
    parser.add_argument("--warmup", type=float, default=5.0)
    parser.add_argument("--port", type=int, default=8765)
    parser.add_argument("--redis-url", default="redis://127.0.0.1:6379/0")
    parser.add_argument(
        "--postgres-url",
        default="postgresql+psycopg://postgres@127.0.0.1:5432/test",
        help="with --workers over 1: the database a private schema is made in",
    )
    parser.add_argument("--json", action="store_true", help="end with one JSON line of the figures")
    parser.add_argument("--profile", help="py-spy output of the server (.svg flame graph, .json speedscope)")
    parser.add_argument(
        "--find-max", action="store_true", help="for 1 and 2 processes: the largest trial count with both p99 < 100 ms"
    )
    parser.add_argument("--max-trials", type=int, default=400)
    parser.add_argument("--step", type=int, default=25)
    parser.add_argument("--max-probes", type=int, default=6, help="runs per process count in --find-max")
    args = parser.parse_args()

    if not 0 <= args.agent_drivers <= args.trials:
        parser.error(f"--agent-drivers must be between 0 and --trials ({args.trials})")
    if not 0 <= args.watchers <= args.trials:
        parser.error(f"--watchers must be between 0 and --trials ({args.trials})")
    load = Load(
        args.trials,
        args.workers or 1,
        args.pattern,
        args.mazes,
        args.open_at_once,
        args.benchmark,
        args.agent_drivers,
        args.watchers,
        args.fresh_caches,
    )
    if args.find_max:
        result = {}
        for workers in (1, 2) if args.workers is None else (args.workers,):
            best, runs = find_max(replace(load, workers=workers), args)
            console.print(
                f"[bold]largest trial count with both p99 < {P99_GOAL_MS:.0f} ms, {workers} "
                f"process(es): {best}[/] ({len(runs)} runs of {args.duration:.0f} s)"
            )
            result[f"max_trials_{workers}_workers"] = best
            result[f"runs_{workers}_workers"] = runs
        if args.json:
            print(json.dumps(result))
        return
    figures = run_load(
        load,
        args.duration,
        args.warmup,
        args.port,
        args.redis_url,
        args.postgres_url,
        args.profile,
    )
    report(figures)
    if args.json:
        print(json.dumps(figures))


if __name__ == "__main__":
    main()

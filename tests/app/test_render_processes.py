"""Simulator frames drawn in render processes of their own (setting RENDER_PROCESSES): the same
JPEG as drawn in the server, delivered to the Driver, and a render process killed mid-trial
costs no frame."""

from __future__ import annotations

import asyncio
import base64
import os
import signal
import time

import pytest

from app.backends.render import RenderProcesses, render_jpeg
from app.mazes import Mazes
from app.preparation import builders_for
from app.settings import Settings
from bench.live import ServerProcesses
from sim.core.geometry import heading_angle
from sim.trial import events as ev
from tests.app.live import platform_settings
from tests.app.trial_play import move, start_trial

POSES = [(100, 0), (200, 3), (300, 5), (400, 7)]


@pytest.fixture(scope="module")
def maze_and_graph(tmp_path_factory):
    mazes = Mazes(Settings(data_dir=tmp_path_factory.mktemp("data"), cache_dir=tmp_path_factory.mktemp("cache")))
    name = mazes.names()[0]
    return mazes.load(name), mazes.graph(name)


def continuous(graph, node: int, heading: int) -> tuple[float, float, float]:
    x, y = graph.nodes[node % graph.n]
    return float(x), float(y), float(heading_angle(heading))


def test_a_render_process_draws_the_frame_the_server_would(maze_and_graph):
    maze, graph = maze_and_graph
    renderer = RenderProcesses(1, None)

    async def draw() -> list[bytes]:
        return [await renderer.jpeg(maze, *continuous(graph, n, h)) for n, h in POSES]

    try:
        drawn = asyncio.run(draw())
        assert renderer._pool._processes, "drawn in the pool's process, not by the fallback here"
    finally:
        renderer.close()
    assert drawn == [render_jpeg(maze, *continuous(graph, n, h)) for n, h in POSES]


def test_a_killed_render_process_costs_no_frame(maze_and_graph):
    maze, graph = maze_and_graph
    renderer = RenderProcesses(1, None)

    async def draw() -> list[bytes]:
        frames = [await renderer.jpeg(maze, *continuous(graph, *POSES[0]))]
        for pid in list(renderer._pool._processes):  # the pool's own processes
            os.kill(pid, signal.SIGKILL)
        for pose in POSES[1:]:  # the first after the kill is drawn in the server, then a new pool
            frames.append(await renderer.jpeg(maze, *continuous(graph, *pose)))
        return frames

    try:
        drawn = asyncio.run(draw())
        assert renderer._pool._processes, "a new render process serves the later frames"
    finally:
        renderer.close()
    assert drawn == [render_jpeg(maze, *continuous(graph, n, h)) for n, h in POSES]


@pytest.mark.settings(render_processes=1)
def test_the_driver_sees_frames_drawn_in_a_render_process(server, trials):
    services = server.services
    assert isinstance(services.trials.backends.renderer, RenderProcesses)
    trial = trials.new()

    async def play() -> list[bytes]:
        async with (
            trial.seat("commander") as commander,
            trial.seat("driver") as driver,
        ):
            await start_trial(commander, driver)
            seen = []
            for action in ("left", "left", "right", "forward"):
                executed = await driver.event("move_executed", move_id=(await move(driver, action))["move_id"])
                frame = await driver.event("frame", start=driver.received.index(executed))
                seen.append(base64.b64decode(frame["jpeg"]))
            return seen

    seen = asyncio.run(play())
    maze = services.mazes.load(services.mazes.names()[0])
    # Each recorded frame is the render, in this process, at one of the poses the trial logged
    # (a frame drawn in the render process is recorded when it comes back, which on a loaded
    # machine may be after the next pose event: the log's order does not pair them).
    poses = [
        (e.payload["x"], e.payload["y"], e.payload["heading"])
        for e in services.log.load(trial.id)
        if e.is_(ev.PoseSampled)
    ]
    frames = [
        services.trials.frames.read(trial.id, e.seq) for e in services.log.load(trial.id) if e.is_(ev.FrameRecorded)
    ]
    assert len(frames) >= 5, "the first frame and one after each move"
    renders = {render_jpeg(maze, *pose) for pose in poses}
    assert all(jpeg in renders for jpeg in frames)
    assert set(seen) <= set(frames), "the Driver saw the frames recorded"


def spawned(pids: list[int]) -> list[int]:
    """The process pools' workers among `pids` (started by multiprocessing's spawn)."""
    found = []
    for pid in pids:
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                if b"spawn_main" in f.read():
                    found.append(pid)
        except OSError:
            pass
    return found


def alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/status") as f:
            return "State:\tZ" not in f.read()  # a zombie has exited
    except OSError:
        return False


@pytest.mark.slow
def test_render_processes_and_maze_builders_end_with_a_server_killed_by_sigkill(tmp_path, server_process):
    # On an empty cache the maze builders start with the server too (they read the maps for the
    # grouping into layouts): a builder outlived a killed server before it followed it.
    server = server_process(platform_settings(tmp_path, render_processes=1, cache_dir=tmp_path / "cache")).start()
    workers = 1 + builders_for(0)  # the render process and a builder per core
    try:
        deadline = time.monotonic() + 60
        while len(spawned(children := ServerProcesses(server.proc.pid).pids())) < workers:
            assert time.monotonic() < deadline, f"{len(spawned(children))} of {workers} child processes started"
            time.sleep(0.1)
        renderers = set(children) - {server.proc.pid}
    finally:
        server.kill()
    deadline = time.monotonic() + 60
    while any(alive(p) for p in renderers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(alive(p) for p in renderers), "a child process outlived its server"

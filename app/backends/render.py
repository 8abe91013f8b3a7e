"""Where simulator frames are drawn. A first-person render and its JPEG take about 2 ms of CPU,
most of it holding the GIL, so in a server's own threads they take the GIL from the event loop
that serves every trial. `RenderProcesses` (setting `RENDER_PROCESSES`, default 1) draws them in
processes of their own, which load each maze by name from the same library; `InThread` draws
them in a thread of the server (RENDER_PROCESSES=0, and the fallback while a lost render process
is replaced)."""

from __future__ import annotations

import asyncio
import logging
import os
import threading
import time
from collections import OrderedDict
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from multiprocessing import get_context
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import cv2
import numpy as np

if TYPE_CHECKING:
    from sim.core.maze import Maze
    from sim.tasks.library import MazeLibrary

logger = logging.getLogger(__name__)
FRAME_SIZE = (320, 240)
JPEG_QUALITY = 80
WORKER_MAZES_KEPT = 16  # mazes a render process keeps loaded (a few MB each without their graphs)


def render_jpeg(maze: Maze, x: float, y: float, theta: float) -> bytes:
    """The camera frame at a continuous pose, as the rover's camera sends it (320x240 JPEG)."""
    from sim.robot.render import first_person  # imported when the first frame is taken

    image = first_person(maze, x, y, theta, size=FRAME_SIZE)
    ok, buffer = cv2.imencode(".jpg", np.ascontiguousarray(image), [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    if not ok:
        raise RuntimeError("JPEG encoding of a simulator frame failed")
    return buffer.tobytes()


class FrameRenderer(Protocol):
    async def jpeg(self, maze: Maze, x: float, y: float, theta: float) -> bytes: ...

    def close(self) -> None: ...


class InThread:
    async def jpeg(self, maze: Maze, x: float, y: float, theta: float) -> bytes:
        return await asyncio.to_thread(render_jpeg, maze, x, y, theta)

    def close(self) -> None:
        pass


class RenderProcesses:
    def __init__(self, processes: int, benchmark: Path | None) -> None:
        self.processes, self.benchmark = processes, benchmark
        self._pool = self._start()

    def _start(self) -> ProcessPoolExecutor:
        # spawn, not fork: the server has threads (and a loop) that a forked child must not inherit
        return ProcessPoolExecutor(
            self.processes,
            mp_context=get_context("spawn"),
            initializer=_start_worker,
            initargs=(str(self.benchmark) if self.benchmark else None, os.getpid()),
        )

    def warm_up(self) -> None:
        """Start the processes and their imports now, not at the first trial's first frame."""
        for _ in range(self.processes):
            self._pool.submit(_loaded_mazes)

    async def jpeg(self, maze: Maze, x: float, y: float, theta: float) -> bytes:
        pool = self._pool
        try:
            return await asyncio.get_running_loop().run_in_executor(
                pool, _render, maze.name, maze.content_hash, x, y, theta
            )
        except BrokenProcessPool:  # a render process died (killed, out of memory): a new pool
            logger.error("a render process was lost; starting new ones, this frame drawn here")
            if self._pool is pool:
                self._pool = self._start()
            return await asyncio.to_thread(render_jpeg, maze, x, y, theta)

    def close(self) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)


# -- in a render process --------------------------------------------------------------
_library: MazeLibrary | None = None
_mazes: OrderedDict[str, Maze] = OrderedDict()


def _start_worker(benchmark: str | None, server: int) -> None:
    from sim.tasks.library import MazeLibrary

    global _library
    _library = MazeLibrary(benchmark=Path(benchmark) if benchmark else None, cache=False)
    threading.Thread(target=_exit_with, args=(server,), daemon=True).start()


def _exit_with(server: int) -> None:
    """A server killed with SIGKILL cannot stop its render processes: each follows it itself
    (`server` is the pid that started it: it may have died before this process got here)."""
    while os.getppid() == server:
        time.sleep(0.5)
    os._exit(0)


def _loaded_mazes() -> int:
    return len(_mazes)


def _render(name: str, content_hash: str, x: float, y: float, theta: float) -> bytes:
    maze = _mazes.pop(name, None)
    if maze is None:
        assert _library is not None  # set by the pool's initializer
        maze = _library.load(name)
    _mazes[name] = maze
    while len(_mazes) > WORKER_MAZES_KEPT:
        _mazes.popitem(last=False)
    if maze.content_hash != content_hash:  # the file changed under the server: draw nothing wrong
        _mazes.pop(name)
        raise RuntimeError(f"maze {name!r} differs from the server's copy")
    return render_jpeg(maze, x, y, theta)

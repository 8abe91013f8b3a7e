"""Where simulator frames are drawn. A first-person render and its JPEG take about 2 ms of CPU,
most of it holding the GIL, so in a server's own threads they take the GIL from the event loop
that serves every trial. `RenderProcesses` (setting `RENDER_PROCESSES`, default 1) draws them in
processes of their own; `InThread` draws them in a thread of the server (RENDER_PROCESSES=0, and
the fallback while a lost render process is replaced).

A render process keeps the scene (`sim.robot.render.Scene`: what a frame needs of a maze, about 1 MB)
of every maze it has drawn lately, `SCENES_KEPT` of them: more than the live trials' mazes of a
busy server, so a frame never waits for a maze to load. A maze's scene is read from the cache by
its contents (`Maze.content_hash`, sent with every frame), or built from the library once; a trial
asks for it when it starts (`prepare`), before its first frame."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import os
from collections import OrderedDict
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from multiprocessing import get_context
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import cv2
import numpy as np

from app.children import follow

if TYPE_CHECKING:
    from sim.core.maze import Maze
    from sim.robot.render import Scene
    from sim.tasks.library import MazeLibrary

logger = logging.getLogger(__name__)
FRAME_SIZE = (320, 240)
JPEG_QUALITY = 80
SCENES_KEPT = 256  # maze scenes a render process keeps (about 1.2 MB each)


def render_jpeg(maze: Maze, x: float, y: float, theta: float) -> bytes:
    """The camera frame at a continuous pose, as the rover's camera sends it (320x240 JPEG)."""
    from sim.robot.render import scene  # imported when the first frame is taken

    return scene_jpeg(scene(maze), x, y, theta)


def scene_jpeg(scene: Scene, x: float, y: float, theta: float) -> bytes:
    """`render_jpeg` from the maze's scene."""
    from sim.robot.render import draw

    image = draw(scene, x, y, theta, size=FRAME_SIZE)
    ok, buffer = cv2.imencode(".jpg", np.ascontiguousarray(image), [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    if not ok:
        raise RuntimeError("JPEG encoding of a simulator frame failed")
    return buffer.tobytes()


class FrameRenderer(Protocol):
    def prepare(self, maze: Maze) -> None:
        """Ready what the maze's frames need, ahead of the first (without waiting for it)."""
        ...

    async def jpeg(self, maze: Maze, x: float, y: float, theta: float) -> bytes: ...

    def close(self) -> None: ...


class InThread:
    def prepare(self, maze: Maze) -> None:
        pass  # the first frame builds the maze's scene, kept while the maze is

    async def jpeg(self, maze: Maze, x: float, y: float, theta: float) -> bytes:
        return await asyncio.to_thread(render_jpeg, maze, x, y, theta)

    def close(self) -> None:
        pass


class RenderProcesses:
    def __init__(self, processes: int, benchmark: Path | None, cache_dir: Path | None = None) -> None:
        self.processes, self.benchmark, self.cache_dir = processes, benchmark, cache_dir
        self._pool = self._start()

    def _start(self) -> ProcessPoolExecutor:
        # spawn, not fork: the server has threads (and a loop) that a forked child must not inherit
        return ProcessPoolExecutor(
            self.processes,
            mp_context=get_context("spawn"),
            initializer=_start_worker,
            initargs=(
                str(self.benchmark) if self.benchmark else None,
                str(self.cache_dir) if self.cache_dir else None,
                os.getpid(),
            ),
        )

    def warm_up(self) -> None:
        """Start the processes and their imports now, not at the first trial's first frame."""
        for _ in range(self.processes):
            self._pool.submit(_kept_scenes)

    def prepare(self, maze: Maze) -> None:
        with contextlib.suppress(BrokenProcessPool):  # the first frame finds it broken and replaces it
            self._pool.submit(_prepare, maze.name, maze.content_hash)

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
_cache_dir: Path | None = None
_scenes: OrderedDict[str, Scene] = OrderedDict()  # by content hash, the latest drawn last


def _start_worker(benchmark: str | None, cache_dir: str | None, server: int) -> None:
    from sim.tasks.library import MazeLibrary

    global _library, _cache_dir
    _cache_dir = Path(cache_dir) if cache_dir else None
    _library = MazeLibrary(benchmark=Path(benchmark) if benchmark else None, cache=False, cache_dir=_cache_dir)
    follow(server)


def _kept_scenes() -> int:
    return len(_scenes)


def _scene_for(name: str, content_hash: str) -> Scene:
    """The scene of the server's copy of maze `name` (its contents hash to `content_hash`)."""
    from sim.robot.render import cached_scene, load_scene

    scene = _scenes.pop(content_hash, None) or load_scene(content_hash, _cache_dir)
    if scene is None:
        assert _library is not None  # set by the pool's initializer
        maze = _library.load(name)
        if maze.content_hash != content_hash:  # the file changed under the server: draw nothing wrong
            raise RuntimeError(f"maze {name!r} differs from the server's copy")
        scene = cached_scene(maze, _cache_dir)
    _scenes[content_hash] = scene
    while len(_scenes) > SCENES_KEPT:
        _scenes.popitem(last=False)
    return scene


def _prepare(name: str, content_hash: str) -> None:
    _scene_for(name, content_hash)  # kept here; nothing sent back


def _render(name: str, content_hash: str, x: float, y: float, theta: float) -> bytes:
    return scene_jpeg(_scene_for(name, content_hash), x, y, theta)

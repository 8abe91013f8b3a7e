"""Mazes prepared before anyone waits: what a trial needs of a maze, built into the cache ahead.

A trial's seats need four things of its maze, each cached on disk by the maze's contents: its
decoded maps (`Maze`), the robot's graph with its all-pairs tables (`NavGraph.for_robot`), that
graph's ray table (`RayTable`) and the render scene (`sim.robot.render`). Its layout signature
(`sim.tasks.layouts`) is cached too: the server's grouping of the library into layouts puts off
the mazes being prepared and then reads theirs, rather than decode their maps a second time at
once (the marker does not name the signature's version: one missing is made where it is read).
Built, they take a few tenths of a second a maze; read back, a few milliseconds. `prepare_maze` builds what is missing,
then writes the maze's marker `prepared/KEY-VERSION` (KEY: its map files' bytes,
`MazeLibrary.maps_key`; VERSION: the four caches' versions), so that telling whether a maze is
prepared decodes nothing. The caches survive restarts and upgrades: a cache written by a version
whose tables differ holds no marker of this version, and its mazes are prepared again, in the
background.

The building itself is done in builder processes of their own, one per core by default
(`Settings.maze_builders`; spawned at the first maze that needs them): in the server's threads
its Python and numpy held the GIL from the requests, and creating 200 trials on a fresh install
answered in 183 ms at p95 (36.5 ms with a builder process). With one builder, 200 new trials'
mazes were built one after another, and their seats waited up to 45 s. The server's threads
only check markers, and wait.

`Preparation.run` does it from the server's warm-up thread (`Mazes.warm_up`), once the library
is grouped into layouts (on a fresh install `Preparation.sign` has the builders decode every map
for it first, 7 s for the benchmark's against 13 s in the server's thread; the dashboard shows the
mazes ungrouped meanwhile): every maze
of the library, in order, one at a time per builder, with its progress in the log and on the
experimenter's dashboard. The mazes of trials just created (`first`) are prepared at once, in
threads of their own (as many as builders) that take them in turn. A seat whose maze is not
prepared yet (`ensure`) waits for the thread that has it in hand, else has it built at once:
behind at most a maze a thread, never behind the rest of the library. `robotslang mazes prepare`
does the same on demand, in as many builders (`app.commands`).
"""

from __future__ import annotations

import asyncio
import json
import logging
import os
import threading
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from multiprocessing import get_context
from pathlib import Path
from typing import TYPE_CHECKING

from app.children import follow
from sim.core.maze import LABELS_CACHE_VERSION

if TYPE_CHECKING:
    from sim.tasks.library import MazeLibrary

logger = logging.getLogger(__name__)
LOG_EVERY_S = 5.0  # progress lines while preparing


def builders_for(setting: int) -> int:
    """The builder processes to use: `setting`, where 0 means one per core."""
    return setting or max(1, os.cpu_count() or 1)


def prepared_version() -> str:
    """The versions of the four caches a prepared maze holds: a marker of another names other tables."""
    from sim.core import navgraph, observations
    from sim.robot.render import SCENE_CACHE_VERSION

    return f"labels{LABELS_CACHE_VERSION}-graph{navgraph.CACHE_VERSION}-rays{observations.CACHE_VERSION}-scene{SCENE_CACHE_VERSION}"


def marker(key: str, cache_dir: Path) -> Path:
    """The marker of a prepared maze whose map files have `key` (`MazeLibrary.maps_key`)."""
    return cache_dir / "prepared" / f"{key}-{prepared_version()}"


def prepare_maze(library: MazeLibrary, name: str, cache_dir: Path) -> bool:
    """Build what is missing of what a trial needs of maze `name` into `cache_dir`; False when it
    was prepared already (nothing decoded). Raises `MazeError` for a malformed map."""
    from sim.core.navgraph import NavGraph
    from sim.core.observations import RayTable
    from sim.robot.render import cached_scene
    from sim.tasks.layouts import LayoutSignature

    key = library.maps_key(name)
    done = marker(key, cache_dir)
    if done.exists():
        return False
    maze = library.load(name)
    graph = NavGraph.for_robot(maze, cache_dir=cache_dir)
    RayTable.build(maze, graph, cache_dir=cache_dir)
    cached_scene(maze, cache_dir)
    LayoutSignature.cached(key, lambda: maze, cache_dir)  # what grouping the library into layouts reads of it
    done.parent.mkdir(parents=True, exist_ok=True)
    done.write_text(json.dumps({"maze": name, "content_hash": maze.content_hash}))
    return True


@dataclass(frozen=True)
class Progress:
    ready: int  # prepared, found so or built here
    total: int  # the library's mazes
    built: int  # of those ready, prepared by this process
    failed: int  # malformed maps: their trials fail as they would have

    @property
    def done(self) -> bool:
        return self.total > 0 and self.ready + self.failed >= self.total

    def __str__(self) -> str:
        failed = f", {self.failed} failed" if self.failed else ""
        return f"{self.ready} of {self.total} mazes ready ({self.built} prepared here{failed})"


class Preparation:
    """Every maze of the library prepared in the server's warm-up thread, those of new trials at once."""

    def __init__(
        self, library: Callable[[], MazeLibrary], benchmark: Path | None, cache_dir: Path, builders: int = 1
    ) -> None:
        self._library, self.benchmark, self.cache_dir = library, benchmark, cache_dir
        self.builders = builders  # processes, and threads taking the library's or new trials' mazes
        self._builder: ProcessPoolExecutor | None = None  # the processes that build, once one is needed
        self._lock = threading.Lock()
        self._quiet = threading.Condition(self._lock)  # notified when no new trial's maze waits
        self._first: deque[str] = deque()  # mazes of trials created, in order
        self._ready: set[str] = set()
        self._failed: set[str] = set()
        self._making: dict[str, Future[None]] = {}  # per maze, while it is prepared
        self._built = 0
        self._stop = threading.Event()
        self._firsts: set[threading.Thread] = set()  # prepare new trials' mazes, while there are any

    def stop(self) -> None:
        """`run` returns after the mazes in hand (their caches are whole: each is written, then
        renamed), and so do the threads on new trials' mazes, which this waits for."""
        with self._lock:
            self._stop.set()
            self._quiet.notify_all()
            firsts, builder = list(self._firsts), self._builder
        for thread in firsts:
            thread.join()
        if builder is not None:
            builder.shutdown(wait=True, cancel_futures=True)

    def first(self, name: str) -> None:
        """A trial was created on `name`: it is prepared now, by one of the threads (one a builder)
        that take the new trials' mazes in turn (even while the library is still being grouped
        into layouts)."""
        with self._lock:
            if name in self._ready or name in self._first or self._stop.is_set():
                return
            self._first.append(name)
            if len(self._firsts) < min(self.builders, len(self._first)):
                thread = threading.Thread(target=self._prepare_firsts, name="mazes-first", daemon=True)
                self._firsts.add(thread)
                thread.start()

    def _prepare_firsts(self) -> None:
        while True:
            with self._lock:
                name = self._next_locked(deque())
                if name is None:
                    # Under the lock: a trial created from now on starts another.
                    self._firsts.discard(threading.current_thread())
                    self._quiet.notify_all()
                    return
            self.ensure(name)

    def in_hand(self, name: str) -> bool:
        """Whether maze `name` is being prepared, or waits to be as a new trial's."""
        with self._lock:
            return name in self._making or name in self._first

    def progress(self) -> Progress:
        total = len(self._library().names())
        with self._lock:
            return Progress(len(self._ready), total, self._built, len(self._failed))

    def ensure(self, name: str) -> None:
        """Return once maze `name` is prepared (or found malformed): at once where it is, after the
        thread that has it in hand, else after having it built."""
        making, mine = self._claim(name)
        if making is None:
            return
        if not mine:
            making.result()
            return
        built = None
        try:
            built = not self._prepared(name) and self._built_by(name, *self._submit(name))
        except Exception as err:
            self._failure(name, err)
        finally:
            self._settle(name, making, built)

    async def ready(self, name: str) -> None:
        """`ensure` for a coroutine: no thread is held while the maze is built (a crowd of seats on
        mazes being built held every thread of the event loop's executor, which other trials'
        frames are written in)."""
        making, mine = self._claim(name)
        if making is None:
            return
        if not mine:
            await asyncio.wrap_future(making)
            return
        built = None
        try:
            if not await asyncio.to_thread(self._prepared, name):
                built_here, builder = self._submit(name)
                try:
                    built = await asyncio.wrap_future(built_here)
                except BrokenProcessPool:
                    built = await asyncio.to_thread(self._lost, builder, name)
            else:
                built = False
        except Exception as err:
            self._failure(name, err)
        finally:
            self._settle(name, making, built)

    def _claim(self, name: str) -> tuple[Future[None] | None, bool]:
        """None where the maze is prepared or found malformed; else the future of its preparation,
        and whether the caller is the one to do it."""
        with self._lock:
            if name in self._ready or name in self._failed:
                return None, False
            making = self._making.get(name)
            if making is not None:
                return making, False
            making = self._making[name] = Future()
            return making, True

    def _settle(self, name: str, making: Future[None], built: bool | None) -> None:
        """`built` None: it failed."""
        with self._lock:
            if built is None:
                self._failed.add(name)
            else:
                self._ready.add(name)
                self._built += built
            del self._making[name]
        making.set_result(None)

    def _failure(self, name: str, err: Exception) -> None:
        # A malformed map: logged, and its trial fails as it would have. A server stopping has let
        # its builder go: nothing to say.
        if not self._stop.is_set():
            logger.error("maze %s could not be prepared: %s", name, err)

    def _prepared(self, name: str) -> bool:
        return marker(self._library().maps_key(name), self.cache_dir).exists()

    def _submit(self, name: str, only_signature: bool = False) -> tuple[Future[bool], ProcessPoolExecutor]:
        """`build_maze` in a builder process (started here the first time)."""
        with self._lock:
            if self._builder is None:
                self._builder = builder_pool(self.benchmark, self.cache_dir, self.builders)
            builder = self._builder
        return builder.submit(build_maze, name, only_signature), builder

    def _built_by(self, name: str, built: Future[bool], builder: ProcessPoolExecutor) -> bool:
        try:
            return built.result()
        except BrokenProcessPool:
            return self._lost(builder, name)

    def _lost(self, builder: ProcessPoolExecutor, name: str) -> bool:
        """A builder process was lost (killed, out of memory), and with it the pool: this maze is
        built here (and so is each other maze the pool had in hand), the next in a new pool."""
        logger.error("mazes: the process preparing them was lost; maze %s prepared in the server", name)
        self._forget(builder)
        return prepare_maze(self._library(), name, self.cache_dir)

    def _forget(self, builder: ProcessPoolExecutor | None) -> None:
        """A lost pool: the next maze starts a new one."""
        with self._lock:
            if self._builder is builder:
                self._builder = None

    def sign(self) -> None:
        """Every maze's decoded maps and layout signature cached by the builders, a maze a builder
        at a time (a new trial's maze goes between them): what grouping the library into layouts
        reads. In the server's warm-up thread the same decoding took 12 s for the benchmark's mazes
        and held the GIL from the requests; a maze it leaves undone (malformed, or its builder
        lost) the grouping decodes itself."""
        started = time.monotonic()
        rest = deque(self._library().names())
        logger.info("mazes: reading %d maps to group them into layouts", len(rest))

        def next_map() -> str | None:
            """The library's next maze not in hand; none while new trials' mazes wait for the
            builders: their seats wait on them, and a maze prepared is read for its signature too
            (with 200 new trials on a fresh install, the reading shared the builders with them, and
            the last seat was welcomed after 14 s)."""
            with self._lock:
                while self._firsts and not self._stop.is_set():
                    self._quiet.wait()
                while rest and not self._stop.is_set():
                    name = rest.popleft()
                    if name not in self._making and name not in self._first and name not in self._ready:
                        return name
                return None

        def sweep() -> None:
            while (name := next_map()) is not None:
                if self._prepared(name):
                    continue  # its signature is among what it was prepared with
                builder = None
                try:
                    signed, builder = self._submit(name, only_signature=True)
                    signed.result()
                except BrokenProcessPool:
                    self._forget(builder or self._builder)
                except Exception:  # noqa: BLE001 - malformed, or the pool stopped: the grouping sees to it
                    pass

        for thread in self._sweeps(sweep, "mazes-sign"):
            thread.join()
        if not self._stop.is_set():
            logger.info("mazes: maps read in %.1f s", time.monotonic() - started)

    def run(self) -> None:
        """Prepare every maze of the library, those of new trials first, in a thread per builder,
        logging the progress."""
        started = time.monotonic()
        names = self._library().names()
        logger.info("mazes: preparing what trials need of %d mazes in %s", len(names), self.cache_dir)
        rest = deque(names)

        def sweep() -> None:
            while (name := self._next(rest)) is not None:
                self.ensure(name)

        for thread in self._sweeps(sweep, "mazes-sweep"):
            while thread.is_alive():
                thread.join(LOG_EVERY_S)
                if thread.is_alive():
                    logger.info("mazes: %s", self.progress())
        if not self._stop.is_set():
            logger.info("mazes: %s in %.1f s", self.progress(), time.monotonic() - started)

    def _sweeps(self, sweep: Callable[[], None], name: str) -> list[threading.Thread]:
        """`sweep` started in a thread per builder."""
        threads = [threading.Thread(target=sweep, name=name, daemon=True) for _ in range(self.builders)]
        for thread in threads:
            thread.start()
        return threads

    def _next(self, rest: deque[str]) -> str | None:
        """The next maze to prepare: a new trial's, else the library's next; None once stopped or done."""
        with self._lock:
            return self._next_locked(rest)

    def _next_locked(self, rest: deque[str]) -> str | None:
        for queue in (self._first, rest):
            while queue and not self._stop.is_set():
                name = queue.popleft()
                if name not in self._ready and name not in self._failed:
                    return name
        return None


def builder_pool(benchmark: Path | None, cache_dir: Path, builders: int) -> ProcessPoolExecutor:
    """`builders` processes that prepare mazes of the library (`build_maze`) into `cache_dir`."""
    return ProcessPoolExecutor(
        builders,
        mp_context=get_context("spawn"),
        initializer=_start_builder,
        initargs=(benchmark, cache_dir, os.getpid()),
    )


# -- in the builder process ----------------------------------------------------------------
_builder_library: tuple[MazeLibrary, Path] | None = None


def _start_builder(benchmark: Path | None, cache_dir: Path, server: int) -> None:
    from sim.tasks.library import MazeLibrary

    follow(server)  # a builder outlives no server, killed or not (its caches are written, then renamed)

    # A batch job to the kernel: the server's requests and moves, waking, are not kept waiting behind
    # it (with a builder per core at normal priority, creating 200 trials on a fresh install
    # answered at p95 in 150 ms against 43 ms with one), while it keeps its share of the CPU (niced,
    # a loaded machine's other work left it so little that seats waited longer than with one builder).
    if hasattr(os, "sched_setscheduler"):  # Linux
        os.sched_setscheduler(0, os.SCHED_BATCH, os.sched_param(0))
    # One thread: there is a builder per core already, and OpenCV's own threads only add CPU there
    # (two builders on the 2-core machine, 60 benchmark mazes: 45.2 and 44.6 ms a maze against 46.6
    # and 45.8 with them, alternated).
    import cv2

    cv2.setNumThreads(1)
    global _builder_library
    _builder_library = MazeLibrary(benchmark, cache=False, cache_dir=cache_dir), cache_dir


def build_maze(name: str, only_signature: bool = False) -> bool:
    """`prepare_maze` in a process of `builder_pool`; where `only_signature`, what grouping the
    library reads of the maze (its decoded maps and layout signature) and False. Raises `MazeError`
    for a malformed map."""
    assert _builder_library is not None  # set by the pool's initializer
    library, cache_dir = _builder_library
    if only_signature:
        library.signature(name, cache_dir)
        return False
    return prepare_maze(library, name, cache_dir)

"""The mazes trials run in: the library (bundled + benchmark), their graphs, start poses and the
pictures the Commander sees (the map with the three landmarks and the image of the next target).

Memory: a maze and its navigation graph are about 27 MB (the graph's all-pairs tables). A
process holds those of the mazes its live trials use (their backends keep them) and of the
`MAZES_KEPT` mazes used last; any other maze is released, so a server that runs trials on all of
the benchmark's mazes over a study stays bounded (`python -m bench.memory`)."""

from __future__ import annotations

import math
import threading
import weakref
from collections import OrderedDict
from collections.abc import Callable, Iterator, Mapping
from functools import lru_cache
from typing import TYPE_CHECKING, Generic, TypeVar

import cv2
import numpy as np

from app.map_text import walls
from app.preparation import Preparation, builders_for
from app.settings import Settings
from sim.core.dynamics import Pose
from sim.core.geometry import TABLE_WIDTH_M, world_to_pixel
from sim.core.labels import LABEL_BGR, OBJECT_LABELS, Label
from sim.core.maze import Maze

if TYPE_CHECKING:
    from sim.core.observations import RayTable
    from sim.tasks.layouts import Layout
    from sim.tasks.library import MazeLibrary
from sim.core.navgraph import NavGraph

TARGET_VIEW_DISTANCE_M = 0.35
LANDMARK_RADIUS_M = 0.045  # the disc that marks a landmark on the Commander's map
MIN_START_DISTANCE_M = 0.5
MAZES_KEPT = 8  # mazes (and graphs) kept beyond those of live trials
PICTURES_KEPT = 64  # maps and target images (a few hundred kB per maze)


T = TypeVar("T")


class Kept(Generic[T]):
    """`make(name)` once per name while anything uses the result, and for the last `size` names
    asked for: a maze in a live trial is never loaded twice, one nobody uses is released. Trials
    open in threads: a lock per name, so that trials starting together on one maze share it, and
    trials on different mazes load theirs side by side (one lock for all made a crowd of trials
    opening at once wait on each other's mazes)."""

    def __init__(self, make: Callable[[str], T], size: int) -> None:
        self.make, self.size = make, size
        self._alive: weakref.WeakValueDictionary[str, T] = weakref.WeakValueDictionary()
        self._recent: OrderedDict[str, T] = OrderedDict()
        self._lock = threading.Lock()  # the dictionaries, held briefly
        self._making: dict[str, threading.Lock] = {}  # per name, while it is made

    def __call__(self, name: str) -> T:
        with self._lock:
            value = self._alive.get(name)
            making = self._making.setdefault(name, threading.Lock()) if value is None else None
        if making is not None:
            with making:
                with self._lock:
                    value = self._alive.get(name)
                if value is None:
                    value = self.make(name)
                with self._lock:
                    self._alive[name] = value
                    self._making.pop(name, None)
        assert value is not None  # alive already, or made above
        with self._lock:
            self._recent[name] = value
            self._recent.move_to_end(name)
            while len(self._recent) > self.size:
                self._recent.popitem(last=False)
        return value

    def __len__(self) -> int:
        return len(self._alive)


class UnknownMaze(LookupError):
    pass


class _LayoutsWhenRead(Mapping[str, str]):
    def __init__(self, mazes: Mazes) -> None:
        self._mazes, self._names = mazes, mazes.names()

    def __contains__(self, name: object) -> bool:
        return name in self._names

    def __getitem__(self, name: str) -> str:
        return self._mazes.layouts()[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._names)

    def __len__(self) -> int:
        return len(self._names)


class Mazes:
    def __init__(self, settings: Settings) -> None:
        self.settings = settings
        self._library: MazeLibrary | None = None
        self._layouts: dict[str, str] | None = None
        self._layouts_lock = threading.Lock()  # the startup warm-up and a page: one grouping
        self._warming: threading.Thread | None = None
        self._stop_warming = threading.Event()
        self.preparation = Preparation(
            lambda: self.library, settings.benchmark, settings.cache_dir, builders_for(settings.maze_builders)
        )
        self.load = Kept(self._load, MAZES_KEPT)
        self.graph = Kept(self._graph, MAZES_KEPT)
        self.rays = Kept(self._rays, MAZES_KEPT)
        self.map_png = lru_cache(maxsize=PICTURES_KEPT)(self._map_png)
        self.target_jpeg = lru_cache(maxsize=3 * PICTURES_KEPT)(self._target_jpeg)
        self.map_walls = lru_cache(maxsize=PICTURES_KEPT)(self._map_walls)

    @property
    def library(self) -> MazeLibrary:
        if self._library is None:
            from sim.tasks.library import MazeLibrary

            self._library = MazeLibrary(  # `Kept` caches
                benchmark=self.settings.benchmark, cache=False, cache_dir=self.settings.cache_dir
            )
        return self._library

    def names(self) -> list[str]:
        return list(self.library.names())

    def layouts(self, stop: threading.Event | None = None) -> dict[str, str]:
        """Each maze, in library order -> the id of its physical layout (`sim.tasks.layouts`). The
        grouping is cached on disk; the first process to ask decodes every map (60 ms a map, 12 s
        for the benchmark's): the server asks at startup, in a thread (`warm_up`)."""
        with self._layouts_lock:
            if self._layouts is None:
                grouped = self.library.layouts(cache_dir=self.settings.cache_dir, stop=stop, preparing=self.preparation)
                self._layouts = self._by_maze(grouped)
            return self._layouts

    def layouts_if_grouped(self) -> dict[str, str] | None:
        """`layouts()` where the library is grouped, in this process or in the cache; None while
        the warm-up is still grouping it (a fresh install's first start): a page shows the mazes
        without waiting."""
        if self._layouts is None:
            stored = self.library.stored_layouts(self.settings.cache_dir)
            if stored is None:
                return None
            self._layouts = self._by_maze(stored)
        return self._layouts

    def _by_maze(self, grouped: list[Layout]) -> dict[str, str]:
        from sim.tasks.layouts import layout_of

        of = layout_of(grouped)
        return {name: of[name] for name in self.names()}

    def layouts_when_read(self) -> Mapping[str, str]:
        """`layouts()`, grouped only once a layout is read: creating a trial for a team that has
        played nothing reads none, so a fresh install's first trials do not wait for the grouping."""
        return _LayoutsWhenRead(self)

    def warm_up(self) -> None:
        """At the server's start, in a thread: the layouts (which a study's lobby waits for), then
        every maze prepared for trials (`app.preparation`)."""
        self._warming = threading.Thread(target=self._warm, name="mazes", daemon=True)
        self._warming.start()

    def _warm(self) -> None:
        from sim.tasks.library import LayoutsStopped

        if self.layouts_if_grouped() is None:
            self.preparation.sign()  # the maps read by the builders, not in this process
        try:
            self.layouts(stop=self._stop_warming)
        except LayoutsStopped:  # the next process to ask goes on from the maps read
            return
        self.preparation.run()

    def close(self) -> None:
        """Stop the warm-up within a map: a thread still decoding maps (OpenCV) as the interpreter
        exits aborts the process (SIGABRT, exit status 134), as a test run's did after passing."""
        self._stop_warming.set()
        self.preparation.stop()
        if self._warming is not None:
            self._warming.join()

    def _load(self, name: str) -> Maze:
        if name not in self.names():
            raise UnknownMaze(f"unknown maze {name!r}")
        return self.library.load(name)

    def _graph(self, name: str) -> NavGraph:
        maze = self.load(name)
        self.preparation.ensure(name)  # then read from the cache, and its rays and scene are there too
        graph = NavGraph.for_robot(maze, cache_dir=self.settings.cache_dir)
        graph.moves  # noqa: B018 -- its moves compiled here, where the graph loads, not on the event loop at a seat's start
        return graph

    def _rays(self, name: str) -> RayTable:
        """The observation of every pose of the maze's graph: a simulator frame's rays are a lookup."""
        from sim.core.observations import RayTable

        return RayTable.build(self.load(name), self.graph(name), cache_dir=self.settings.cache_dir)

    def _map_png(self, name: str) -> bytes:
        """The Commander's map: the walls, and each landmark as a disc in its benchmark colour
        (as the annotated `maze.map-fixed.png` colours it), as the paper's Commander saw them."""
        return commander_map_png(self.load(name))

    def _map_walls(self, name: str) -> list[dict[str, object]]:
        """The map's walls for its description in words (`app.map_text`)."""
        return [wall.as_json() for wall in walls(self.load(name))]

    def landmarks(self, name: str) -> dict[str, tuple[float, float]]:
        """Each landmark's centre in metres, for the legend and the next-target mark."""
        return {obj: (float(x), float(y)) for obj, (x, y) in self.load(name).objects.items()}

    def distance_m(self, name: str, obj: str, pose: tuple[float, float, float]) -> float:
        """How far a pose is from an object's centre, in metres: what a claim is judged by."""
        ox, oy = self.load(name).objects[obj]
        return math.hypot(pose[0] - ox, pose[1] - oy)

    def full_map_png(self, name: str) -> bytes:
        """Walls and objects: for the experimenter only."""
        return _encode(".png", self.load(name).image())

    def start_pose(self, name: str, first_target: str, seed: int) -> Pose:
        """A random pose away from the first target, from which it can be reached."""
        maze, graph = self.load(name), self.graph(name)
        goal = graph.nearest_node(*maze.objects[first_target])
        rng = np.random.default_rng(seed)
        far = np.nonzero((graph.dist[:, goal] >= MIN_START_DISTANCE_M) & np.isfinite(graph.dist[:, goal]))[0]
        candidates = far if far.size else np.nonzero(np.isfinite(graph.dist[:, goal]))[0]
        return Pose(int(rng.choice(candidates)), int(rng.integers(8)))

    def _target_jpeg(self, name: str, target: str) -> bytes:
        """The target as the robot's camera would see it from a nearby free spot."""
        from sim.robot.render import first_person

        maze, graph = self.load(name), self.graph(name)
        ox, oy = maze.objects[target]
        x, y = _view_point(maze, graph, ox, oy)
        theta = math.atan2(oy - y, ox - x)
        return _encode(".jpg", first_person(maze, x, y, theta, size=(320, 240)))


def commander_map(maze: Maze) -> np.ndarray:
    """The walls-only map with the objects' own pixels and a disc (white rim) at each centre."""
    image = maze.image(walls_only=True).copy()
    objects = np.isin(maze.labels, OBJECT_LABELS)
    image[objects] = maze.image()[objects]
    radius_px = int(round(LANDMARK_RADIUS_M / TABLE_WIDTH_M * (maze.labels.shape[1] - 1)))
    for label in OBJECT_LABELS:
        if label.word not in maze.objects:
            continue
        col, row = world_to_pixel(*maze.objects[label.word])
        centre = (int(round(float(col))), int(round(float(row))))
        cv2.circle(image, centre, radius_px + 3, (255, 255, 255), -1, lineType=cv2.LINE_8)
        cv2.circle(image, centre, radius_px, LABEL_BGR[label], -1, lineType=cv2.LINE_8)
    return image


def commander_map_png(maze: Maze) -> bytes:
    return _encode(".png", commander_map(maze))


def _view_point(maze: Maze, graph: NavGraph, ox: float, oy: float) -> tuple[float, float]:
    """The node nearest TARGET_VIEW_DISTANCE_M from the object with no wall between."""
    d = np.hypot(graph.nodes[:, 0] - ox, graph.nodes[:, 1] - oy)
    for i in np.argsort(np.abs(d - TARGET_VIEW_DISTANCE_M)):
        x, y = graph.nodes[i]
        if _clear_line(maze, x, y, ox, oy):
            return float(x), float(y)
    x, y = graph.nodes[int(np.argmin(d))]
    return float(x), float(y)


def _clear_line(maze: Maze, x0: float, y0: float, x1: float, y1: float) -> bool:
    t = np.linspace(0.0, 0.85, 40)  # stop short of the object itself
    cols, rows = world_to_pixel(x0 + (x1 - x0) * t, y0 + (y1 - y0) * t)
    h, w = maze.labels.shape
    rows = np.clip(np.round(rows).astype(int), 0, h - 1)
    cols = np.clip(np.round(cols).astype(int), 0, w - 1)
    return bool(np.all(maze.walls[rows, cols] == Label.FLOOR))


def _encode(ext: str, image: np.ndarray) -> bytes:
    ok, buffer = cv2.imencode(ext, np.ascontiguousarray(image))
    if not ok:
        raise RuntimeError(f"could not encode a {ext} image")
    return buffer.tobytes()

"""Procedural mazes in the benchmark's format and style.

A generated maze looks like a benchmark map: a white table edge, chains of straight wall
segments in the six wall colours on black floor, and the three objects as filled circles in
open floor. The same seed always gives the same maze, byte for byte. A candidate is kept only
when the objects reach each other on the benchmark's navigation graph and the routes between
consecutive objects (jar -> mug -> paddle) need turns; otherwise the next candidate is drawn
from a seed derived from the same one.
"""

from __future__ import annotations

import cv2
import numpy as np

from sim.core.geometry import MAP_HEIGHT_PX, MAP_WIDTH_PX, pixel_to_world
from sim.core.labels import OBJECT_LABELS, WALL_LABELS, Label
from sim.core.maze import Maze, MazeError
from sim.core.navgraph import NavGraph
from sim.core.validation import unreachable_pairs

# As on the benchmark's maps: a white table edge 8-26 px wide, walls 10-14 px thick in straight
# segments of 0.2-0.6 m, 20-35 segments, objects drawn as discs of radius 40 px.
BORDER_PX = (10, 26)
WALL_THICKNESS_PX = (10, 15)
SEGMENT_LENGTH_PX = (120, 360)
SEGMENTS = (20, 33)
CHAIN_SEGMENTS = (2, 8)
SEGMENT_TRIES = 6
# Turn at a joint, degrees: mostly straight on or square, sometimes diagonal.
TURNS = (0.0, 90.0, -90.0, 45.0, -45.0, 135.0, -135.0)
TURN_P = (0.4, 0.22, 0.22, 0.06, 0.06, 0.02, 0.02)
OBJECT_RADIUS_PX = 40
OBJECT_CLEARANCE_PX = 50  # open floor between an object's rim and the nearest wall
OBJECT_SPACING_PX = 420  # about 0.74 m between object centres
SPOT_STEP_PX = 10  # lattice of candidate object centres
WALL_GAP_PX = 110  # a new segment keeps this far from other walls: gaps stay passable

# What makes a maze worth navigating: each consecutive route bends and detours. On the real
# maps 90% of consecutive routes have 3 or more turns and a detour of 2.1 or more (median 4.1).
MIN_TURNS = 3
MIN_DETOUR = 1.8  # route length over straight-line distance
MIN_CONNECTED = 0.8  # share of node pairs joined by a path (real maps: 0.88 or more for 90%)
TURN_TOLERANCE_M = 0.12  # deviations smaller than this are not turns
MAX_ATTEMPTS = 100  # wall layouts tried
PLACEMENTS = 30  # object placements tried per layout


def generate_maze(seed: int, name: str | None = None) -> Maze:
    """The maze of `seed`: deterministic, mutually reachable objects, routes with turns."""
    if seed < 0:
        raise ValueError(f"maze seed must be 0 or more, got {seed}")
    name = name or f"gen-s{seed}"
    for attempt in range(MAX_ATTEMPTS):
        rng = np.random.default_rng([seed, attempt])
        walls = draw_walls(rng)
        spots = open_spots(walls)
        graph = None
        for _ in range(PLACEMENTS):
            centres = pick_centres(rng, spots)
            if centres is None:
                break
            maze = Maze.from_labels(draw_objects(walls, centres), name, walls)
            if graph is None:
                # The graph depends on the walls only: build it once per layout, and from
                # then on place objects only where the largest connected region is.
                graph = NavGraph.build(maze, use_cache=False)
                if graph.reachable_fraction() < MIN_CONNECTED:
                    break
                spots = spots[in_main_region(graph, spots)]
            if not unreachable_pairs(maze, graph) and has_structure(maze, graph):
                return maze
    raise MazeError(
        f"{name}: no maze with reachable objects and turning routes in {MAX_ATTEMPTS} attempts from seed {seed}"
    )


# -- drawing ----------------------------------------------------------------------
def draw_walls(rng: np.random.Generator) -> np.ndarray:
    """Walls-only label grid: the table edge and chains of straight coloured segments."""
    walls = np.zeros((MAP_HEIGHT_PX, MAP_WIDTH_PX), dtype=np.uint8)
    left, top, right, bottom = (int(v) for v in rng.integers(*BORDER_PX, size=4))
    walls[:top] = walls[MAP_HEIGHT_PX - bottom :] = Label.WHITE
    walls[:, :left] = walls[:, MAP_WIDTH_PX - right :] = Label.WHITE
    inner = (left, top, MAP_WIDTH_PX - 1 - right, MAP_HEIGHT_PX - 1 - bottom)
    edge = walls != Label.FLOOR

    target = int(rng.integers(*SEGMENTS))
    thickness = int(rng.integers(*WALL_THICKNESS_PX))
    room = _Room(walls, edge)
    placed = 0
    for _ in range(20 * target):
        if placed >= target:
            break
        placed += _draw_chain(rng, room, inner, thickness, target - placed)
    return walls


class _Room:
    """The walls drawn so far, with each floor pixel's distance to them, for clearance tests.

    A segment is tested against the walls as they were before the segment it continues (or,
    for a chain's first segment from the table edge, against the chain walls alone), so that
    it may touch what it grows from and keeps WALL_GAP_PX from everything else.
    """

    def __init__(self, walls: np.ndarray, edge: np.ndarray):
        self.walls = walls
        self.clear = cv2.distanceTransform((~edge).astype(np.uint8), cv2.DIST_L2, 5)
        self.clear_inside = np.full(walls.shape, np.inf, dtype=np.float32)
        self.clear_before_last = self.clear.copy()

    def fits(self, corners: np.ndarray, clear: np.ndarray) -> bool:
        c0, r0 = np.maximum(corners.min(axis=0), 0)
        c1, r1 = np.minimum(corners.max(axis=0) + 1, [MAP_WIDTH_PX, MAP_HEIGHT_PX])
        window = np.zeros((r1 - r0, c1 - c0), dtype=np.uint8)
        cv2.fillConvexPoly(window, corners - [c0, r0], 1)
        return bool((clear[r0:r1, c0:c1][window.astype(bool)] > WALL_GAP_PX).all())

    def paint(self, corners: np.ndarray, colour: Label) -> None:
        self.clear_before_last = self.clear.copy()
        cv2.fillConvexPoly(self.walls, corners, int(colour))
        # Only distances up to the gap matter, so the new wall's field is needed near it only.
        c0, r0 = np.maximum(corners.min(axis=0) - WALL_GAP_PX - 2, 0)
        c1, r1 = np.minimum(corners.max(axis=0) + WALL_GAP_PX + 3, [MAP_WIDTH_PX, MAP_HEIGHT_PX])
        window = np.ones((r1 - r0, c1 - c0), dtype=np.uint8)
        cv2.fillConvexPoly(window, corners - [c0, r0], 0)
        near = cv2.distanceTransform(window, cv2.DIST_L2, 5)
        for clear in (self.clear, self.clear_inside):
            np.minimum(clear[r0:r1, c0:c1], near, out=clear[r0:r1, c0:c1])


def _draw_chain(
    rng: np.random.Generator, room: _Room, inner: tuple[int, int, int, int], thickness: int, budget: int
) -> int:
    """One polyline of segments, from the table edge or open floor; returns segments drawn."""
    x0, y0, x1, y1 = inner
    if rng.random() < 0.4:  # start on the table edge, heading inward
        side = int(rng.integers(4))  # left, right, top, bottom
        along = rng.uniform(y0 + 80, y1 - 80) if side < 2 else rng.uniform(x0 + 80, x1 - 80)
        start: tuple[float, float] = ((x0, along), (x1, along), (along, y0), (along, y1))[side]
        angle = (0.0, 180.0, 90.0, 270.0)[side]
        from_edge = True
    else:
        start = (rng.uniform(x0 + 100, x1 - 100), rng.uniform(y0 + 100, y1 - 100))
        angle = 90.0 * int(rng.integers(4))
        from_edge = False

    n = min(int(rng.integers(*CHAIN_SEGMENTS)), budget)
    point = np.array(start, dtype=np.float64)
    colour = None
    drawn = 0
    for k in range(n):
        if k > 0:
            against = room.clear_before_last
        else:
            against = room.clear_inside if from_edge else room.clear
        for _ in range(SEGMENT_TRIES):  # a blocked direction is retried before the chain ends
            turn = 0.0 if k == 0 and from_edge else float(rng.choice(TURNS, p=TURN_P))
            heading = np.deg2rad(angle + turn + rng.normal(0.0, 5.0))
            end = point + rng.uniform(*SEGMENT_LENGTH_PX) * np.array([np.cos(heading), np.sin(heading)])
            if not (x0 < end[0] < x1 and y0 < end[1] < y1):
                continue
            corners = _segment_corners(point, end, thickness + int(rng.integers(-1, 2)))
            if room.fits(corners, against):
                break
        else:
            break
        # Real chains change colour at most joints but not all.
        choices = [c for c in WALL_LABELS if c != colour] if rng.random() < 0.85 else list(WALL_LABELS)
        colour = choices[int(rng.integers(len(choices)))]
        room.paint(corners, colour)
        drawn += 1
        angle += turn
        point = end
    return drawn


def _segment_corners(a: np.ndarray, b: np.ndarray, thickness: int) -> np.ndarray:
    """Corners (column, row) of a straight wall from a to b, square-ended like the real maps."""
    d = (b - a) / max(np.linalg.norm(b - a), 1e-9)
    n = np.array([-d[1], d[0]]) * thickness / 2.0
    return np.round([a + n, b + n, b - n, a - n]).astype(np.int32)


def open_spots(walls: np.ndarray) -> np.ndarray:
    """Pixels (column, row), on a coarse lattice, where an object disc sits in open floor."""
    clearance = cv2.distanceTransform((walls == Label.FLOOR).astype(np.uint8), cv2.DIST_L2, 5)
    rows, cols = np.nonzero(clearance[::SPOT_STEP_PX, ::SPOT_STEP_PX] > OBJECT_RADIUS_PX + OBJECT_CLEARANCE_PX)
    return np.stack([cols, rows], axis=1) * SPOT_STEP_PX


def in_main_region(graph: NavGraph, spots: np.ndarray) -> np.ndarray:
    """Which spots lie nearest to a node of the graph's largest connected region."""
    if graph.n == 0 or spots.size == 0:
        return np.zeros(len(spots), dtype=bool)
    reach = np.isfinite(graph.dist)
    main = reach[reach.sum(axis=1).argmax()]
    x, y = pixel_to_world(spots[:, 0], spots[:, 1])
    inside: np.ndarray = main[graph.nearest_nodes(np.stack([x, y], axis=1))]
    return inside


def pick_centres(rng: np.random.Generator, spots: np.ndarray) -> list[tuple[int, int]] | None:
    """Three spots at least OBJECT_SPACING_PX apart (jar, mug, paddle), or None if crowded."""
    centres: list[tuple[int, int]] = []
    for _ in OBJECT_LABELS:
        for _ in range(50):
            if spots.size == 0:
                return None
            c, r = (int(v) for v in spots[int(rng.integers(len(spots)))])
            if all(np.hypot(c - pc, r - pr) >= OBJECT_SPACING_PX for pc, pr in centres):
                centres.append((c, r))
                break
        else:
            return None
    return centres


def draw_objects(walls: np.ndarray, centres: list[tuple[int, int]]) -> np.ndarray:
    """The label grid: the walls with jar, mug and paddle drawn as discs at `centres`."""
    labels = walls.copy()
    for label, centre in zip(OBJECT_LABELS, centres):
        cv2.circle(labels, centre, OBJECT_RADIUS_PX, int(label), thickness=-1, lineType=cv2.LINE_8)
    return labels


# -- structure ----------------------------------------------------------------------
def route_turns(graph: NavGraph, path: list[int]) -> int:
    """Corners of a route once the grid's staircase is smoothed away."""
    if len(path) < 3:
        return 0
    points = graph.nodes[path].astype(np.float32).reshape(-1, 1, 2)
    corners = cv2.approxPolyDP(points, TURN_TOLERANCE_M, closed=False)
    return max(len(corners) - 2, 0)


def has_structure(maze: Maze, graph: NavGraph) -> bool:
    """Every consecutive route (jar -> mug -> paddle) turns and detours enough."""
    names = [label.word for label in OBJECT_LABELS]
    for a, b in zip(names, names[1:]):
        i = graph.nearest_node(*maze.objects[a])
        j = graph.nearest_node(*maze.objects[b])
        straight = float(np.hypot(*np.subtract(graph.nodes[i], graph.nodes[j])))
        if graph.dist[i, j] < MIN_DETOUR * straight or route_turns(graph, graph.path(i, j)) < MIN_TURNS:
            return False
    return True

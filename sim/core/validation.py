"""Checks a maze must pass before people or agents are sent through it."""

from __future__ import annotations

from itertools import combinations

import numpy as np

from sim.core.maze import Maze, MazeError
from sim.core.navgraph import NavGraph


def unreachable_pairs(maze: Maze, graph: NavGraph) -> list[tuple[str, str]]:
    """Object pairs whose nearest navigation nodes have no path between them."""
    names = list(maze.objects)
    if graph.n == 0:
        return list(combinations(names, 2))
    nodes = dict(zip(names, graph.nearest_nodes(np.array([maze.objects[o] for o in names]))))
    return [(a, b) for a, b in combinations(names, 2) if not np.isfinite(graph.dist[nodes[a], nodes[b]])]


def check_reachable(maze: Maze, graph: NavGraph | None = None, source: str | None = None) -> NavGraph:
    """Raise MazeError unless every object reaches every other on the (benchmark) graph.

    `source` names the map file in the message (default: the maze's name). Returns the graph,
    so callers that go on navigating need not build it twice.
    """
    graph = graph if graph is not None else NavGraph.build(maze)
    pairs = unreachable_pairs(maze, graph)
    if pairs:
        where = source or maze.name
        listed = ", ".join(f"{a} and {b}" for a, b in pairs)
        if graph.n == 0:
            raise MazeError(f"{where}: no navigable floor, so no object can reach another ({listed})")
        raise MazeError(f"{where}: objects cannot reach each other on the navigation graph: {listed}")
    return graph

"""The navigation graph: the benchmark's construction, its invariants, and the disk cache."""

from __future__ import annotations

import numpy as np
import pytest

from sim.core.geometry import GRID_STEP_M, SUCCESS_RADIUS_M
from sim.core.maze import Maze
from sim.core.navgraph import NavGraph, candidate_grid
from sim.tasks.benchmark import Benchmark
from sim.tasks.library import MazeLibrary
from tests.sim.helpers import open_table, wall_at_x

RUNS = ("Run_318", "Run_114", "Run_135")


@pytest.fixture(scope="module")
def bench(benchmark_path):
    return Benchmark(benchmark_path)


def test_candidate_grid_is_the_benchmarks():
    positions, ij, pixels = candidate_grid()
    assert len(positions) == 36 * 30
    assert np.allclose(positions[1], [0.07, 0.0]) and np.allclose(positions[36], [0.0, 0.07])
    # Truncated pixels: x = 0.07 m is column 0.07 / 2.4638 * 1400 = 39.77 -> 39.
    assert tuple(pixels[1]) == (1174, 39)


@pytest.mark.parametrize("run", RUNS)
@pytest.mark.parametrize("mode", ["benchmark", "exact"])
def test_graph_invariants_on_benchmark_maps(bench, run, mode):
    g = NavGraph.build(bench.maze(run), mode, use_cache=False)
    assert np.allclose(g.dist, g.dist.T, equal_nan=False)
    assert np.all(np.diag(g.dist) == 0)
    # Triangle inequality through every intermediate node k (on a sample of k).
    for k in range(0, g.n, max(1, g.n // 25)):
        through = g.dist[:, [k]] + g.dist[[k], :]
        assert np.all(g.dist <= through + 1e-9)
    # Next hops reproduce the distances: d(i, j) = |i - hop| + d(hop, j).
    rng = np.random.default_rng(0)
    for i, j in rng.integers(0, g.n, size=(300, 2)):
        if not np.isfinite(g.dist[i, j]):
            assert g.next_hop[i, j] == -1 and g.path(i, j) == []
            continue
        path = g.path(i, j)
        assert path[0] == i and path[-1] == j
        length = np.linalg.norm(np.diff(g.nodes[path], axis=0), axis=1).sum()
        assert length == pytest.approx(g.dist[i, j], abs=1e-9)


def test_benchmark_mode_drops_diagonals_exact_mode_keeps(bench):
    maze = bench.maze("Run_318")
    bm, ex = NavGraph.build(maze, "benchmark", use_cache=False), NavGraph.build(maze, "exact", use_cache=False)
    assert bm.n == ex.n
    # Some pairs of diagonal neighbours are not joined in benchmark mode, so paths can only get longer.
    assert np.all(bm.dist[np.isfinite(bm.dist)] >= ex.dist[np.isfinite(bm.dist)] - 1e-9)
    assert (bm.dist > ex.dist + 1e-6).any()
    # About 6% of node pairs have no path: reported as infinity, never an error.
    assert 0 < 1 - bm.reachable_fraction() < 0.2
    far = np.argwhere(~np.isfinite(bm.dist))[0]
    assert bm.topological_distance(bm.nodes[far[0]], bm.nodes[far[1]]) == float("inf")


def test_nodes_keep_clear_of_walls():
    labels = wall_at_x(open_table(), 1.0)
    g = NavGraph.build(Maze.from_labels(labels, "wall"), use_cache=False)
    # The wall at x = 1.0 m (10 px thick) plus 40 px clearance removes the columns near it.
    xs = np.unique(np.round(g.nodes[:, 0], 3))
    assert not np.any(np.abs(xs - 1.0) < GRID_STEP_M)
    # The wall spans the table: the two sides are not connected.
    left, right = g.nearest_node(0.5, 1.0), g.nearest_node(1.5, 1.0)
    assert g.dist[left, right] == float("inf")


def test_open_table_distances_are_grid_geometry():
    g = NavGraph.build(Maze.from_labels(open_table(), "open"), "exact", use_cache=False)
    a, b = g.nearest_node(0.7, 0.7), g.nearest_node(0.7 + 5 * 0.07, 0.7 + 3 * 0.07)
    assert g.dist[a, b] == pytest.approx(3 * np.sqrt(2) * 0.07 + 2 * 0.07)


def test_graph_is_cached_by_maze_and_mode(tmp_path):
    maze = Maze.from_labels(open_table(), "open")
    g1 = NavGraph.build(maze, "benchmark", cache_dir=tmp_path)
    files = list((tmp_path / "navgraph").glob("*.arrays"))
    assert len(files) == 1 and maze.content_hash in files[0].name and "benchmark" in files[0].name
    g2 = NavGraph.build(maze, "benchmark", cache_dir=tmp_path)
    assert np.array_equal(g1.dist, g2.dist) and np.array_equal(g1.forward, g2.forward)
    # A torn cache file is rebuilt, not trusted.
    files[0].write_bytes(b"not an npz")
    g3 = NavGraph.build(maze, "benchmark", cache_dir=tmp_path)
    assert np.array_equal(g1.next_hop, g3.next_hop)


def test_unknown_mode_is_refused():
    with pytest.raises(ValueError, match="unknown edge mode 'diagonal'"):
        NavGraph.build(Maze.from_labels(open_table(), "open"), "diagonal")


def test_objects_block_makes_a_move_into_a_landmark_a_collision(tmp_path):
    maze = Maze.from_labels(open_table(), "open")
    walls_only = NavGraph.build(maze, cache_dir=tmp_path)
    live = NavGraph.for_robot(maze, cache_dir=tmp_path)
    assert not walls_only.objects_block and live.objects_block
    jar = np.asarray(maze.objects["jar"])
    # The node a few steps left of the jar, heading +x (heading 0) toward it.
    for graph, collides in ((walls_only, False), (live, True)):
        node = graph.nearest_node(*(jar - [0.21, 0.0]))
        while graph.forward[node, 0] >= 0 and graph.nodes[graph.forward[node, 0], 0] < jar[0]:
            node = int(graph.forward[node, 0])
        assert (graph.forward[node, 0] < 0) == collides
    # Nothing else changes: the open floor is navigable in both, and the cache keeps them apart.
    assert live.n < walls_only.n
    assert NavGraph.build(maze, cache_dir=tmp_path).n == walls_only.n


def test_with_objects_blocking_every_target_is_reachable_from_the_others(tmp_path):
    library = MazeLibrary()
    for name in library.names()[:4]:
        maze = library.load(name)
        graph = NavGraph.build(maze, cache_dir=tmp_path, objects_block=True)
        goals = [graph.nearest_node(*xy) for xy in maze.objects.values()]
        assert np.isfinite(graph.dist[np.ix_(goals, goals)]).all()
        near = [np.hypot(*(graph.nodes[g] - xy)) for g, xy in zip(goals, maze.objects.values())]
        assert max(near) < SUCCESS_RADIUS_M

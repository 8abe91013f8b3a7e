"""Ray observations: exact answers on synthetic mazes, hand-checked poses on the benchmark's
maps, and the per-(node, heading) table with its features and cache."""

from __future__ import annotations

import numpy as np
import pytest

from sim.core.geometry import GRID_STEP_M, HEADINGS, TABLE_HEIGHT_M, world_to_pixel
from sim.core.labels import N_LABELS, WALL_LABELS, Label
from sim.core.maze import Maze
from sim.core.navgraph import NavGraph
from sim.core.observations import (
    N_RAYS,
    OBS_FEATURES,
    PX_PER_M_X,
    PX_PER_M_Y,
    RAY_OFFSETS,
    TOO_CLOSE_M,
    RayCaster,
    RayTable,
    cast_rays,
)
from sim.tasks.library import MazeLibrary
from tests.sim.synthetic import BORDER_PX, OBJECT_RADIUS_PX, synthetic_maze

EXACT = 1e-5  # metres: depths are exact to the pixel grid, up to float32 rounding


def test_rays_span_78_degrees_in_13_equal_steps():
    assert np.allclose(np.rad2deg(RAY_OFFSETS), np.linspace(-39, 39, 13))


def test_every_ray_meets_a_wall_across_the_view_at_its_exact_distance():
    # A red wall whose left face is the edge of column 800 - 0.5, tall enough for all 13 rays.
    maze = synthetic_maze([(Label.RED, 800, 100, 811, 1100)])
    x, y = 0.9, 1.0
    col0, _ = world_to_pixel(x, y)
    labels, depth = cast_rays(maze, x, y, 0.0)
    assert labels.tolist() == [Label.RED] * N_RAYS
    ahead = (799.5 - col0) / PX_PER_M_X
    assert np.allclose(depth, ahead / np.cos(RAY_OFFSETS), atol=EXACT)


@pytest.mark.parametrize("row, label", [(499.6, Label.RED), (499.4, Label.WHITE)])
def test_a_ray_meets_every_pixel_it_crosses_however_thinly(row, label):
    # The block's top pixel row spans rows 499.5..500.5: a ray along row 499.6 crosses it by
    # a tenth of a pixel; along row 499.4 it passes just above and goes on to the table edge.
    maze = synthetic_maze([(Label.RED, 800, 500, 811, 600)])
    x, y = 0.9, (1174 - row) / PX_PER_M_Y
    labels, depth = cast_rays(maze, x, y, 0.0, offsets=[0.0])
    assert labels[0] == label
    col0, _ = world_to_pixel(x, y)
    face = 799.5 if label == Label.RED else 1401 - BORDER_PX - 0.5
    assert depth[0] == pytest.approx((face - col0) / PX_PER_M_X, abs=EXACT)


def test_rays_behind_see_the_white_table_edge():
    maze = synthetic_maze([(Label.RED, 800, 100, 811, 1100)])
    x, y = 0.9, 1.0
    col0, _ = world_to_pixel(x, y)
    labels, depth = cast_rays(maze, x, y, np.pi)
    assert labels.tolist() == [Label.WHITE] * N_RAYS
    assert depth[N_RAYS // 2] == pytest.approx((col0 - (BORDER_PX - 0.5)) / PX_PER_M_X, abs=EXACT)


def test_a_ray_leaving_an_unbordered_table_sees_floor_up_to_the_edge():
    maze = synthetic_maze(border=False)
    x, y = 1.2, 1.9
    _, row0 = world_to_pixel(x, y)
    labels, depth = cast_rays(maze, x, y, np.pi / 2, offsets=[0.0])
    assert labels.tolist() == [Label.FLOOR]
    assert depth[0] == pytest.approx((row0 + 0.5) / PX_PER_M_Y, abs=EXACT)
    assert depth[0] == pytest.approx(TABLE_HEIGHT_M - y, abs=2e-3)


@pytest.mark.parametrize("label", [Label.JAR, Label.MUG, Label.PADDLE])
def test_objects_are_seen_on_the_observation_map(label):
    centre = (700, 600)
    maze = synthetic_maze(objects={label: centre})
    (ox, oy) = maze.objects[label.word]
    x, y = ox - 0.4, oy
    labels, depth = cast_rays(maze, x, y, 0.0, offsets=[0.0])
    assert labels[0] == label
    # The disc's near rim, within a pixel (its raster edge is not a perfect circle).
    assert depth[0] == pytest.approx(0.4 - OBJECT_RADIUS_PX / PX_PER_M_X, abs=2 / PX_PER_M_X)


def test_a_ray_origin_off_the_table_is_refused_with_its_position():
    maze = synthetic_maze()
    with pytest.raises(ValueError, match=r"\(-0\.100, 1\.000\) m is off the"):
        cast_rays(maze, -0.1, 1.0, 0.0)


# -- the table over a navigation graph -----------------------------------------------------


@pytest.fixture(scope="module")
def corridor():
    """A blue wall across the table at x ~ 1.4 m with a gap at the bottom; objects in the open."""
    maze = synthetic_maze(
        [(Label.BLUE, 795, 10, 806, 900)],
        objects={Label.JAR: (300, 300), Label.MUG: (1100, 300), Label.PADDLE: (300, 800)},
    )
    graph = NavGraph.build(maze)
    return maze, graph, RayTable.build(maze, graph)


def test_table_shapes_and_types(corridor):
    _, graph, table = corridor
    assert table.labels.shape == (graph.n, HEADINGS, N_RAYS) and table.labels.dtype == np.uint8
    assert table.depth.shape == (graph.n, HEADINGS, N_RAYS) and table.depth.dtype == np.float32
    assert table.too_close.dtype == bool and table.forward_blocked.shape == (graph.n, HEADINGS)


def test_table_rows_are_the_rays_cast_from_each_node(corridor):
    maze, graph, table = corridor
    for node in (0, graph.n // 2, graph.n - 1):
        x, y = graph.nodes[node]
        for k in range(HEADINGS):
            labels, depth = cast_rays(maze, x, y, k * np.pi / 4)
            assert table.labels[node, k].tolist() == labels.tolist()
            assert np.allclose(table.depth[node, k], depth, atol=1e-5)


def test_facing_the_wall_from_the_nearest_node(corridor):
    maze, graph, table = corridor
    # The node left of the wall closest to it, at mid-height: the wall's face is column 794.5.
    i = max(
        i
        for i in range(graph.node_grid.shape[0])
        if graph.node_grid[i, 20] >= 0 and graph.nodes[graph.node_grid[i, 20]][0] < 1.4
    )
    node = graph.node_grid[i, 20]
    col0, _ = world_to_pixel(*graph.nodes[node])
    assert table.labels[node, 0, N_RAYS // 2] == Label.BLUE
    assert table.depth[node, 0, N_RAYS // 2] == pytest.approx((794.5 - col0) / PX_PER_M_X, abs=EXACT)
    assert table.forward_blocked[node, 0] and table.too_close[node, 0, N_RAYS // 2]
    assert not table.forward_blocked[node, 4]  # back into the open


def test_forward_blocked_is_the_graphs_collision(corridor):
    _, graph, table = corridor
    assert np.array_equal(table.forward_blocked, graph.forward < 0)


def test_too_close_is_a_forward_step_plus_the_graphs_guaranteed_clearance(corridor):
    _, _, table = corridor
    assert TOO_CLOSE_M[0] == pytest.approx(GRID_STEP_M + 38 / PX_PER_M_X)
    assert TOO_CLOSE_M[1] == pytest.approx(np.sqrt(2) * GRID_STEP_M + 38 / PX_PER_M_X)
    expected = table.depth < TOO_CLOSE_M[None, :, None]
    assert np.array_equal(table.too_close, expected)


def test_features_encode_labels_depths_flags(corridor):
    _, graph, table = corridor
    f = table.features()
    assert f.shape == (graph.n, HEADINGS, OBS_FEATURES) and f.dtype == np.float32
    onehot = f[..., : N_RAYS * N_LABELS].reshape(graph.n, HEADINGS, N_RAYS, N_LABELS)
    assert np.array_equal(onehot.argmax(-1), table.labels) and np.all(onehot.sum(-1) == 1)
    start = N_RAYS * N_LABELS
    assert np.array_equal(f[..., start : start + N_RAYS], table.depth)
    assert np.array_equal(f[..., start + N_RAYS : start + 2 * N_RAYS], table.too_close)
    assert np.array_equal(f[..., -1], table.forward_blocked)


def test_table_is_cached_by_maze_and_nodes(tmp_path, corridor):
    maze, graph, table = corridor
    first = RayTable.build(maze, graph, cache_dir=tmp_path)
    files = list((tmp_path / "rays").glob("*.arrays"))
    assert len(files) == 1 and maze.content_hash in files[0].name
    again = RayTable.build(maze, graph, cache_dir=tmp_path)
    assert np.array_equal(again.labels, first.labels) and np.array_equal(again.depth, table.depth)
    files[0].write_bytes(b"torn")  # a broken cache file is rebuilt, not trusted
    rebuilt = RayTable.build(maze, graph, cache_dir=tmp_path)
    assert np.array_equal(rebuilt.depth, table.depth)


# -- the benchmark's maps ------------------------------------------------------------------


@pytest.fixture(scope="module")
def run_318(benchmark_path):
    maze = Maze.from_dir(benchmark_path / "mazedata" / "Run_318")
    graph = NavGraph.build(maze)
    return maze, graph, RayTable.build(maze, graph)


# Checked by hand on Run_318's maze.map-fixed.png: from the node at grid (i, j), facing
# heading k, the centre ray's pixel line meets its first non-floor pixel at (col, row).
HAND_CHECKED = [
    ((15, 22), 2, Label.RED, (597, 220)),  # up to the long red wall's lower face
    ((15, 22), 6, Label.BLUE, (597, 434)),  # down to the blue wall of the central box
    ((10, 15), 0, Label.BLUE, (461, 575)),  # right to the box's blue side
    ((10, 15), 4, Label.GREEN, (215, 575)),  # left to the green wall
]


@pytest.mark.parametrize("ij, k, label, pixel", HAND_CHECKED)
def test_hand_checked_rays_on_run_318(run_318, ij, k, label, pixel):
    maze, graph, table = run_318
    node = graph.node_grid[ij]
    assert maze.labels[pixel[1], pixel[0]] == label
    col0, row0 = world_to_pixel(*graph.nodes[node])
    # The ray enters that pixel at its near edge, half a pixel before its centre.
    if k in (0, 4):
        expected = (abs(pixel[0] - col0) - 0.5) / PX_PER_M_X
    else:
        expected = (abs(pixel[1] - row0) - 0.5) / PX_PER_M_Y
    assert table.labels[node, k, N_RAYS // 2] == label
    assert table.depth[node, k, N_RAYS // 2] == pytest.approx(expected, abs=EXACT)


def _dense_ray(maze: Maze, x, y, angle, step_m=5e-5):
    """Reference: sample the ray every 0.05 mm and return the first non-floor pixel it is in
    (so it also sees corners the ray clips by more than that)."""
    t = np.arange(0, 3.3, step_m)
    col, row = world_to_pixel(x + t * np.cos(angle), y + t * np.sin(angle))
    ci, ri = np.floor(col + 0.5).astype(int), np.floor(row + 0.5).astype(int)
    inside = (ci >= 0) & (ci < maze.labels.shape[1]) & (ri >= 0) & (ri < maze.labels.shape[0])
    end = int(np.argmin(inside)) if not inside.all() else t.size
    labels = maze.labels[ri[:end], ci[:end]]
    hits = np.nonzero(labels)[0]
    return (int(labels[hits[0]]), t[hits[0]]) if hits.size else (0, t[end])


def test_table_agrees_with_dense_sampling_on_run_318(run_318):
    maze, graph, table = run_318
    rng = np.random.default_rng(7)
    for node, k, r in zip(rng.integers(graph.n, size=200), rng.integers(8, size=200), rng.integers(N_RAYS, size=200)):
        x, y = graph.nodes[node]
        label, depth = _dense_ray(maze, x, y, k * np.pi / 4 + RAY_OFFSETS[r])
        assert table.labels[node, k, r] == label
        assert table.depth[node, k, r] == pytest.approx(depth, abs=1e-4)  # the reference step


# Maps where a clearance of 40 px all round would flag walls the graph lets the agent reach.
@pytest.mark.parametrize("run", ["Run_318", "Run_124", "Run_135", "Run_146"])
def test_a_wall_too_close_ahead_blocks_the_forward_move(benchmark_path, run):
    maze = Maze.from_dir(benchmark_path / "mazedata" / run)
    graph = NavGraph.build(maze)
    table = RayTable.build(maze, graph)
    # Objects are walkable on the benchmark's graph; walls too close ahead must block.
    centre = N_RAYS // 2
    wall = np.isin(table.labels[:, :, centre], WALL_LABELS)
    close = table.too_close[:, :, centre] & wall
    assert close.any()
    assert table.forward_blocked[close].all()


def test_a_ray_clipping_a_wall_corner_after_a_long_jump_sees_it():
    # Found comparing casters: this ray crosses open floor, then clips the lower-left corner of
    # a magenta pixel (col 1261, row 695) by about a thousandth of a pixel. A jump bounded by a
    # full-resolution float clearance went past it to the red wall 1.05 m away.
    maze = MazeLibrary().load("gen-004")
    x, y, angle = 2.1282949167261185, 1.5039933926321485, -1.436354983279942
    labels, depth = cast_rays(maze, x, y, angle, offsets=[0.0])
    t = np.arange(0.6714, 0.6716, 1e-8)  # the reference, finely around the corner
    col, row = world_to_pixel(x + t * np.cos(angle), y + t * np.sin(angle))
    seen = maze.labels[np.floor(row + 0.5).astype(int), np.floor(col + 0.5).astype(int)]
    first = int(np.argmax(seen != Label.FLOOR))
    assert seen[first] == maze.labels[695, 1261] == labels[0]
    assert depth[0] == pytest.approx(t[first], abs=EXACT)


def test_rays_from_anywhere_agree_with_dense_sampling_on_a_bundled_maze():
    maze = MazeLibrary().load("gen-001")
    rng = np.random.default_rng(3)
    caster = RayCaster(maze.labels)
    x, y = rng.uniform(0.1, 2.3, 150), rng.uniform(0.1, TABLE_HEIGHT_M - 0.1, 150)
    angles = rng.uniform(-np.pi, np.pi, 150)
    labels, depth = caster.cast(x, y, angles)
    for i in range(150):
        label, expected = _dense_ray(maze, x[i], y[i], angles[i])
        assert labels[i] == label
        assert depth[i] == pytest.approx(expected, abs=1e-4)  # the reference step


def test_a_caster_keeps_a_small_clearance_map():
    # A server keeps a caster per live trial's maze (its particle filter): the label grid is
    # the maze's own, and the clearance that rays jump by is a 4x4-block lower bound in bytes.
    maze = MazeLibrary().load("gen-001")
    caster = RayCaster(maze.labels)
    assert np.shares_memory(caster.labels, maze.labels)
    assert caster.clearance.dtype == np.uint8 and caster.clearance.nbytes <= maze.labels.nbytes / 15

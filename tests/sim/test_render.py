"""The Driver's camera and the top-down view, painted from the map."""

from __future__ import annotations

import numpy as np
import pytest

from sim.core.geometry import pixel_to_world, world_to_pixel
from sim.core.labels import LABEL_BGR, WALL_LABELS, Label
from sim.core.maze import Maze
from sim.core.navgraph import NavGraph
from sim.core.observations import N_RAYS, PX_PER_M_X, RayTable, cast_rays
from sim.robot.render import HORIZON, first_person, top_down
from tests.sim.synthetic import synthetic_maze

WALL_COL = 800  # a wide wall's face is the left edge of this column


def _hue_matches(image: np.ndarray, label: Label, tolerance: float = 0.06) -> np.ndarray:
    """Pixels whose colour points the way of `label`'s colour (any brightness above dim)."""
    px = image.astype(np.float64)
    norm = np.linalg.norm(px, axis=-1)
    ref = np.array(LABEL_BGR[label], dtype=np.float64)
    ref /= np.linalg.norm(ref)
    with np.errstate(invalid="ignore", divide="ignore"):
        direction = px / norm[..., None]
    return (norm > 40) & (np.linalg.norm(direction - ref, axis=-1) < tolerance)


def _wall_label(pixel: np.ndarray) -> Label:
    """The wall colour a pixel is a shade of."""
    px = pixel.astype(np.float64) / max(np.linalg.norm(pixel), 1e-9)
    refs = [np.array(LABEL_BGR[w], dtype=np.float64) / np.linalg.norm(LABEL_BGR[w]) for w in WALL_LABELS]
    return WALL_LABELS[int(np.argmin([np.linalg.norm(px - r) for r in refs]))]


def _pose_facing_wall(distance_m: float):
    """(x, y) at `distance_m` left of the face of a wall at column WALL_COL, mid-table."""
    x_face = (WALL_COL - 0.5) / PX_PER_M_X
    return x_face - distance_m, 1.0


def test_frame_is_bgr_uint8_of_the_requested_size():
    maze = synthetic_maze()
    image = first_person(maze, 1.0, 1.0, 0.3)
    assert image.shape == (240, 320, 3) and image.dtype == np.uint8
    assert first_person(maze, 1.0, 1.0, 0.3, size=(640, 480)).shape == (480, 640, 3)


def test_a_silly_size_is_refused():
    with pytest.raises(ValueError, match="too small"):
        first_person(synthetic_maze(), 1.0, 1.0, 0.0, size=(4, 3))


@pytest.mark.parametrize("label", WALL_LABELS)
def test_a_close_wall_fills_the_centre_in_its_colour(label):
    maze = synthetic_maze([(label, WALL_COL, 100, WALL_COL + 11, 1100)])
    x, y = _pose_facing_wall(0.15)
    image = first_person(maze, x, y, 0.0)
    centre = image[int(HORIZON * 240), 160]
    assert _wall_label(centre) == label
    # A wall this close covers most of the picture's height in every column.
    column = image[:, 160]
    assert (column == centre).all(axis=1).mean() > 0.5


def test_walls_shrink_with_distance():
    maze = synthetic_maze([(Label.RED, WALL_COL, 100, WALL_COL + 11, 1100)])
    heights = []
    for distance in (0.2, 0.8):
        image = first_person(maze, *_pose_facing_wall(distance), 0.0)
        heights.append(_hue_matches(image[:, 150:170], Label.RED).any(axis=1).sum())
    # Apparent height goes as 1 / distance: four times nearer, four times taller.
    assert 3.5 < heights[0] / heights[1] < 4.5


@pytest.mark.parametrize("label", [Label.JAR, Label.MUG, Label.PADDLE])
def test_objects_are_drawn_where_they_stand(label):
    maze = synthetic_maze(objects={label: (700, 600)})
    ox, oy = maze.objects[label.word]
    image = first_person(maze, ox - 0.4, oy, 0.0)
    seen = _hue_matches(image, label)
    assert seen.sum() > 300
    cols = np.nonzero(seen.any(axis=0))[0]
    assert cols.min() < 160 < cols.max()  # straight ahead
    # Turned away, it is out of view.
    assert not _hue_matches(first_person(maze, ox - 0.4, oy, np.pi), label).any()


def test_a_wall_in_between_hides_an_object():
    open_maze = synthetic_maze(objects={Label.JAR: (700, 600)})
    ox, oy = open_maze.objects["jar"]
    c, r = (int(v) for v in world_to_pixel(ox - 0.2, oy))
    blocked = synthetic_maze([(Label.RED, c, r - 150, c + 11, r + 150)], objects={Label.JAR: (700, 600)})
    assert _hue_matches(first_person(open_maze, ox - 0.5, oy, 0.0), Label.JAR).sum() > 100
    assert not _hue_matches(first_person(blocked, ox - 0.5, oy, 0.0), Label.JAR).any()


# -- the benchmark's maps ------------------------------------------------------------------


@pytest.fixture(scope="module")
def run_318(benchmark_path):
    maze = Maze.from_dir(benchmark_path / "mazedata" / "Run_318")
    graph = NavGraph.build(maze)
    return maze, graph, RayTable.build(maze, graph)


@pytest.mark.parametrize(
    "ij, k, label", [((15, 22), 2, Label.RED), ((15, 22), 6, Label.BLUE), ((10, 15), 4, Label.GREEN)]
)
def test_the_wall_ahead_on_run_318_is_the_centre_of_the_frame(run_318, ij, k, label):
    maze, graph, _ = run_318
    x, y = graph.nodes[graph.node_grid[ij]]
    image = first_person(maze, x, y, k * np.pi / 4)
    assert _wall_label(image[int(HORIZON * 240), 160]) == label


@pytest.mark.parametrize("label", [Label.JAR, Label.MUG, Label.PADDLE])
def test_each_object_of_run_318_shows_when_the_rays_see_it(run_318, label):
    maze, graph, table = run_318
    centre = N_RAYS // 2
    sees = np.argwhere((table.labels[:, :, centre] == label) & (table.depth[:, :, centre] > 0.15))
    node, k = sees[0]
    x, y = graph.nodes[node]
    seen = _hue_matches(first_person(maze, x, y, k * np.pi / 4), label)
    assert seen[:, 140:180].sum() > 50


# -- top-down ------------------------------------------------------------------------------


def test_top_down_is_the_map_scaled():
    maze = synthetic_maze()
    assert top_down(maze).shape == (588, 700, 3)
    assert top_down(maze, scale=1.0).shape == (1175, 1401, 3)
    with pytest.raises(ValueError, match="scale"):
        top_down(maze, scale=0)


def test_top_down_draws_agent_path_and_rays():
    maze = synthetic_maze([(Label.RED, WALL_COL, 100, WALL_COL + 11, 1100)])
    x, y = _pose_facing_wall(0.5)
    plain = top_down(maze, scale=1.0)
    image = top_down(maze, pose=(x, y, 0.0), path=[(x - 0.6, y - 0.3), (x - 0.3, y), (x, y)], rays=True, scale=1.0)

    def at(px, py):
        c, r = world_to_pixel(px, py)
        return image[int(round(float(r))), int(round(float(c)))]

    assert tuple(at(x + 0.03, y)) == (255, 255, 255)  # the arrow, pointing along +x
    assert tuple(at(x - 0.45, y - 0.15)) == (40, 170, 255)  # on the path
    labels, depth = cast_rays(maze, x, y, 0.0)
    assert labels[N_RAYS // 2] == Label.RED
    # The centre ray's end is marked in the colour of the wall it hits.
    assert tuple(at(x + depth[N_RAYS // 2] - 0.002, y)) == LABEL_BGR[Label.RED]
    assert (image != plain).any(axis=-1).sum() > 500


def test_top_down_walls_only_leaves_the_objects_out():
    maze = synthetic_maze()
    assert _hue_matches(top_down(maze), Label.JAR).sum() > 100
    assert not _hue_matches(top_down(maze, walls_only=True), Label.JAR).any()


# -- held to the grid-marching camera it replaced ----------------------------------------


@pytest.mark.parametrize("run", ["Run_114", "Run_117", "Run_318"])
def test_the_segment_camera_paints_what_the_grid_march_painted(benchmark_path, run):
    """On 40 random poses per map: the columns meet the same walls at the same depths as
    `RayCaster.cast` on the walls grid, but for rays grazing a pixel corner, where the march
    samples 1e-3 px past a crossing and may step into the diagonal pixel (the segments are
    exact there), and the pictures agree. Pixels differ only where a
    wall column's shade does by a level or two: the old march read the wall normal on either
    side of the pixel boundary its ray stopped at, as float32 rounding fell; the segment
    camera reads it inside the wall pixel entered."""
    from bench.render_reference import first_person as reference
    from sim.core.observations import RayCaster
    from sim.robot.render import _camera, _cast_columns, scene

    maze = Maze.from_dir(benchmark_path / "mazedata" / run)
    graph = NavGraph.build(maze)
    caster, cam, drawn = RayCaster(maze.walls), _camera(320, 240), scene(maze)
    rng = np.random.default_rng(7)
    identical = within_two = total = same_columns = columns = 0
    for node in rng.integers(graph.n, size=40):
        x, y = (float(v) for v in graph.nodes[node])
        theta = float(rng.uniform(-np.pi, np.pi))
        angles = theta + cam.column_offsets
        labels, depth = _cast_columns(drawn.walls, cam, x, y, theta, angles)
        want_labels, want_depth = caster.cast(x, y, angles, window=32)
        same_columns += ((labels == want_labels) & (np.abs(depth - want_depth) < 1e-4)).sum()
        columns += labels.size
        assert np.abs(depth - want_depth).max() < 2 / PX_PER_M_X  # a corner is a pixel away at most
        diff = np.abs(first_person(maze, x, y, theta).astype(int) - reference(maze, x, y, theta)).max(axis=2)
        identical, within_two, total = identical + (diff == 0).sum(), within_two + (diff <= 2).sum(), total + diff.size
    assert same_columns / columns > 0.995
    assert identical / total > 0.95 and within_two / total > 0.99


def test_frames_rendered_in_threads_at_once_are_each_their_own_pose():
    """The server renders trials' frames in worker threads: no frame shows another's pose."""
    from concurrent.futures import ThreadPoolExecutor

    maze = synthetic_maze([(Label.RED, WALL_COL, 100, WALL_COL + 11, 1100)])
    poses = [(*_pose_facing_wall(d), 0.0) for d in (0.15, 0.3, 0.6, 1.2)] * 8
    alone = [first_person(maze, *pose) for pose in poses]
    with ThreadPoolExecutor(4) as pool:
        together = list(pool.map(lambda pose: first_person(maze, *pose), poses))
    for a, b in zip(alone, together):
        np.testing.assert_array_equal(a, b)


def test_a_scene_read_back_from_the_cache_draws_the_same_frames(tmp_path):
    """A render process draws from the cached scene alone (no maze): byte for byte the frames of
    the maze itself, at the objects, along a wall, and with the camera inside a wall (where the
    normals are not kept and are computed again)."""
    from sim.robot.render import cached_scene, draw, load_scene
    from sim.tasks.library import MazeLibrary

    maze = MazeLibrary().load("gen-003")
    assert load_scene(maze.content_hash, tmp_path) is None
    cached_scene(maze, tmp_path)
    scene = load_scene(maze.content_hash, tmp_path)
    assert scene is not None
    rows, cols = np.nonzero(maze.walls != Label.FLOOR)
    wall_x, wall_y = (float(v) for v in pixel_to_world(cols[len(cols) // 2], rows[len(rows) // 2]))
    poses = [(*maze.objects[name], theta) for name in maze.objects for theta in (0.0, 2.0, 4.0)]
    poses += [(0.3 + 0.2 * i, 0.4 + 0.13 * i, 0.7 * i) for i in range(10)] + [(wall_x, wall_y, 1.0)]
    for x, y, theta in poses:
        assert np.array_equal(draw(scene, x, y, theta), first_person(maze, x, y, theta)), (x, y, theta)

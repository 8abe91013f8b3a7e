"""The procedural maze generator: deterministic, benchmark format, reachable, with structure;
and the checks that reject malformed maps."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from scipy import ndimage

from sim.core.geometry import MAP_HEIGHT_PX, MAP_WIDTH_PX
from sim.core.labels import LABEL_BGR, OBJECT_LABELS, WALL_LABELS, Label
from sim.core.maze import FIXED_MAP, WALLS_MAP, Maze, MazeError
from sim.core.navgraph import NavGraph
from sim.core.validation import check_reachable
from sim.tasks.generator import generate_maze, route_turns
from sim.tasks.library import BUNDLED_DIR, MANIFEST
from tests.sim.synthetic import synthetic_maze

SEEDS = (3, 4, 5)


@pytest.fixture(scope="module")
def mazes() -> dict[int, Maze]:
    return {seed: generate_maze(seed) for seed in SEEDS}


def png_bytes(maze: Maze, tmp_path) -> tuple[bytes, bytes]:
    folder = maze.save(tmp_path / maze.name)
    return (folder / FIXED_MAP).read_bytes(), (folder / WALLS_MAP).read_bytes()


# -- determinism ------------------------------------------------------------------------
def test_same_seed_gives_the_same_maze_byte_for_byte(mazes, tmp_path):
    again = generate_maze(SEEDS[0])
    assert png_bytes(again, tmp_path / "a") == png_bytes(mazes[SEEDS[0]], tmp_path / "b")
    assert again.objects == mazes[SEEDS[0]].objects


def test_different_seeds_give_different_mazes(mazes):
    grids = [m.labels for m in mazes.values()]
    for i in range(len(grids)):
        for j in range(i + 1, len(grids)):
            assert not np.array_equal(grids[i], grids[j])


def test_bundled_mazes_are_what_the_generator_makes_from_their_manifest_seeds():
    manifest = json.loads((BUNDLED_DIR / MANIFEST).read_text())
    assert [m["name"] for m in manifest["mazes"]] == [f"gen-{i:03d}" for i in range(12)]
    entry = manifest["mazes"][0]
    bundled = Maze.from_dir(BUNDLED_DIR / entry["name"])
    regenerated = generate_maze(entry["seed"], name=entry["name"])
    assert np.array_equal(bundled.labels, regenerated.labels)
    assert np.array_equal(bundled.walls, regenerated.walls)
    for obj, xy in entry["objects"].items():
        assert bundled.objects[obj] == pytest.approx(tuple(xy), abs=1e-3)


# -- format and style -------------------------------------------------------------------
def test_generated_maze_has_the_benchmark_format(mazes):
    for maze in mazes.values():
        assert maze.labels.shape == maze.walls.shape == (MAP_HEIGHT_PX, MAP_WIDTH_PX)
        assert set(np.unique(maze.walls)) <= {Label.FLOOR, *WALL_LABELS}
        assert set(np.unique(maze.labels)) <= set(Label)
        image = maze.image()
        colours = {tuple(int(v) for v in c) for c in np.unique(image.reshape(-1, 3), axis=0)}
        assert colours <= set(LABEL_BGR.values())
        # The table edge is white all round, as on the benchmark's maps.
        for edge in (maze.walls[0], maze.walls[-1], maze.walls[:, 0], maze.walls[:, -1]):
            assert (edge == Label.WHITE).all()
        # Mostly black floor, walls taking about as much as on the real maps (6-12 %).
        assert 0.05 < (maze.walls != Label.FLOOR).mean() < 0.15


def test_objects_are_benchmark_sized_discs_in_open_floor(mazes):
    for maze in mazes.values():
        for label in OBJECT_LABELS:
            blob = maze.labels == label
            # The benchmark draws every object as a disc of radius 40 pixels (5025 pixels).
            assert blob.sum() == pytest.approx(5025, rel=0.02)
            _, count = ndimage.label(blob)
            assert count == 1
            # Under the disc, the walls-only map is floor: objects sit in free space.
            assert (maze.walls[blob] == Label.FLOOR).all()


def test_walls_are_about_20_to_35_straight_segments_in_the_six_colours(mazes):
    for maze in mazes.values():
        inside = maze.walls[30:-30, 30:-30]  # leave the table edge out
        pieces = sum(ndimage.label(inside == c)[1] for c in WALL_LABELS)
        # Same-coloured neighbours in a chain merge, so pieces may undercount segments.
        assert 15 <= pieces <= 35
        assert len({c for c in WALL_LABELS if (inside == c).any()}) >= 5


# -- navigation -------------------------------------------------------------------------
def test_objects_reach_each_other_and_routes_turn(mazes):
    for maze in mazes.values():
        graph = check_reachable(maze)
        names = [label.word for label in OBJECT_LABELS]
        for a, b in zip(names, names[1:]):
            i, j = graph.nearest_node(*maze.objects[a]), graph.nearest_node(*maze.objects[b])
            assert np.isfinite(graph.dist[i, j])
            straight = np.hypot(*(graph.nodes[i] - graph.nodes[j]))
            assert graph.dist[i, j] >= 1.8 * straight
            assert route_turns(graph, graph.path(i, j)) >= 3
        # Most of the floor is one region, as on the real maps.
        assert graph.reachable_fraction() >= 0.8


def test_route_turns_counts_corners_not_grid_steps():
    # An open table (a straight route), and a wall from the bottom edge between the jar and
    # the mug (a route over its top end: one corner), with every diagonal edge.
    objects = {Label.JAR: (200, 600), Label.MUG: (1200, 600), Label.PADDLE: (700, 1050)}
    open_maze = synthetic_maze(objects=objects)
    walled = synthetic_maze(rects=[(Label.RED, 690, 150, 710, 1174)], objects=objects)
    for maze, expected in ((open_maze, 0), (walled, 1)):
        graph = NavGraph.build(maze, mode="exact")
        i, j = graph.nearest_node(*maze.objects["jar"]), graph.nearest_node(*maze.objects["mug"])
        path = graph.path(i, j)
        assert len(path) > 10
        assert route_turns(graph, path) == expected


# -- round trip and rejected maps -------------------------------------------------------
def test_saved_maze_reads_back_identical(mazes, tmp_path):
    maze = mazes[SEEDS[1]]
    back = Maze.from_dir(maze.save(tmp_path / "m").parent)
    assert np.array_equal(back.labels, maze.labels)
    assert np.array_equal(back.walls, maze.walls)
    for name, xy in maze.objects.items():
        assert back.objects[name] == pytest.approx(xy)
    assert back.content_hash == maze.content_hash


def test_map_of_the_wrong_size_is_rejected_naming_the_file(tmp_path):
    path = tmp_path / "r" / "maze" / FIXED_MAP
    path.parent.mkdir(parents=True)
    cv2.imwrite(str(path), np.zeros((600, 800, 3), np.uint8))
    with pytest.raises(MazeError, match=rf"{FIXED_MAP}.*800x600.*expected 1401x1175"):
        Maze.from_dir(path.parent.parent)


def test_map_with_an_unknown_colour_is_rejected_naming_the_file_and_pixel(mazes, tmp_path):
    folder = mazes[SEEDS[0]].save(tmp_path / "r")
    image = cv2.imread(str(folder / FIXED_MAP))
    image[500, 700] = (10, 200, 30)
    cv2.imwrite(str(folder / FIXED_MAP), image)
    with pytest.raises(MazeError, match=rf"{FIXED_MAP}: 1 pixels of unknown colour.*column 700, row 500"):
        Maze.from_dir(folder.parent)


def test_map_missing_an_object_is_rejected_naming_the_file_and_object(mazes, tmp_path):
    folder = mazes[SEEDS[0]].save(tmp_path / "r")
    image = cv2.imread(str(folder / FIXED_MAP))
    image[(image == LABEL_BGR[Label.MUG]).all(axis=2)] = 0
    cv2.imwrite(str(folder / FIXED_MAP), image)
    with pytest.raises(MazeError, match=rf"{FIXED_MAP}: object 'mug' is missing"):
        Maze.from_dir(folder.parent)


def test_objects_that_cannot_reach_each_other_are_rejected_naming_them():
    # A closed white box round the jar: the mug and paddle are outside it.
    box = [
        (Label.WHITE, 100, 450, 400, 465),
        (Label.WHITE, 100, 735, 400, 750),
        (Label.WHITE, 100, 450, 115, 750),
        (Label.WHITE, 385, 450, 400, 750),
    ]
    maze = synthetic_maze(
        rects=box, objects={Label.JAR: (250, 600), Label.MUG: (900, 300), Label.PADDLE: (1100, 900)}, name="boxed"
    )
    with pytest.raises(MazeError, match=r"boxed: objects cannot reach each other.*jar and mug, jar and paddle"):
        check_reachable(maze)
    with pytest.raises(MazeError, match=r"^my/maze.png: "):
        check_reachable(maze, source="my/maze.png")

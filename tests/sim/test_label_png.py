"""Reading map PNGs into label grids: every pixel exactly a palette colour, or a named error."""

from __future__ import annotations

import shutil

import cv2
import numpy as np
import pytest

from sim.core.labels import PALETTE_BGR, Label
from sim.core.maze import Maze, MazeError, read_label_png
from tests.sim.helpers import open_table, wall_at_x


def test_every_palette_colour_reads_back_as_its_label(tmp_path):
    labels = wall_at_x(open_table(), 1.2, Label.BROWN)
    for k, label in enumerate(Label):
        labels[100 + 10 * k : 108 + 10 * k, 300:340] = label
    path = tmp_path / "map.png"
    cv2.imwrite(str(path), PALETTE_BGR[labels])
    assert np.array_equal(read_label_png(path), labels)


@pytest.mark.parametrize("mode", ["RGB", "RGBA", "P"])
def test_a_map_reads_alike_whatever_png_encoder_wrote_it(tmp_path, mode):
    """The benchmark's maps (8-bit RGB, rows filtered None or Sub) are read by a decoder of their
    own; a map saved by another tool (Pillow filters rows by Paeth and Up too, or saves a palette
    or an alpha channel) reads the same."""
    from PIL import Image

    labels = wall_at_x(open_table(), 1.2, Label.BROWN)
    for k, label in enumerate(Label):
        labels[100 + 10 * k : 108 + 10 * k, 300 + 7 * k : 340 + 3 * k] = label
    rgb = np.ascontiguousarray(PALETTE_BGR[labels][..., ::-1])
    path = tmp_path / "map.png"
    image = Image.fromarray(rgb)
    image = image.quantize(colors=len(Label), method=Image.Quantize.FASTOCTREE) if mode == "P" else image.convert(mode)
    image.save(path, optimize=True)
    assert np.array_equal(read_label_png(path), labels)


def test_benchmark_maps_repaint_exactly(benchmark_path):
    for path in sorted((benchmark_path / "mazedata").glob("*/maze/maze.map*.png"))[:6]:
        assert np.array_equal(PALETTE_BGR[read_label_png(path)], cv2.imread(str(path)))


@pytest.mark.parametrize("colour", [(1, 1, 1), (0, 0, 254), (0, 52, 102), (254, 255, 255), (90, 90, 90)])
def test_an_off_palette_pixel_is_named(tmp_path, colour):
    image = PALETTE_BGR[open_table()]
    image[500, 700] = image[900, 20] = colour
    path = tmp_path / "map.png"
    cv2.imwrite(str(path), image)
    with pytest.raises(MazeError, match=r"map\.png: 2 pixels of unknown colour, first at column 700, row 500"):
        read_label_png(path)


def test_decoded_labels_are_cached_by_the_png_contents(tmp_path):
    from sim.tasks.library import MazeLibrary

    library = MazeLibrary()
    run = library.path(library.names()[0])
    first = Maze.from_dir(run, cache_dir=tmp_path)
    cached = list((tmp_path / "labels").glob("*.arrays"))
    assert len(cached) == 1
    again = Maze.from_dir(run, cache_dir=tmp_path)  # read from the cache
    assert np.array_equal(again.labels, first.labels) and np.array_equal(again.walls, first.walls)
    assert again.objects == first.objects and again.content_hash == first.content_hash
    assert again.content_hash == Maze.from_labels(first.labels, "x", first.walls).content_hash
    # Another map is another entry: the key is the files' bytes, not the run's name.
    copy = tmp_path / "copy"
    shutil.copytree(run, copy)
    fixed = copy / "maze" / "maze.map-fixed.png"
    image = cv2.imread(str(fixed))
    row, col = np.argwhere(first.labels == Label.FLOOR)[0]
    image[row, col] = (255, 255, 255)  # a floor pixel painted white: a wall
    cv2.imwrite(str(fixed), image)
    changed = Maze.from_dir(copy, cache_dir=tmp_path)
    assert changed.labels[row, col] == Label.WHITE and changed.content_hash != first.content_hash
    assert len(list((tmp_path / "labels").glob("*.arrays"))) == 2

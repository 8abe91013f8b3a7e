"""The walls of the Commander's map in words' data: a straight wall by its ends, a bent one by
the box it spans, a wall round the whole table as its edge; specks and landmarks left out."""

from __future__ import annotations

import numpy as np

from app.map_text import Wall, WallShape, walls
from sim.core.labels import Label
from sim.core.maze import Maze


def test_straight_bent_and_edge_walls_and_no_specks():
    labels = np.zeros((1175, 1401), np.uint8)
    labels[:12, :], labels[-12:, :], labels[:, :12], labels[:, -12:] = (
        Label.WHITE,
        Label.WHITE,
        Label.WHITE,
        Label.WHITE,
    )
    labels[580:600, 200:800] = Label.RED  # straight, west-east at mid-height: x 0.35..1.41, y 1.02
    labels[100:500, 1000:1020], labels[480:500, 1000:1300] = Label.BLUE, Label.BLUE  # an L in the north-east
    labels[1000:1010, 100:110] = Label.GREEN  # a speck
    labels[900:930, 1100:1130], labels[900:930, 300:330], labels[700:730, 600:630] = Label.JAR, Label.MUG, Label.PADDLE
    found = walls(Maze.from_labels(labels, "words"))
    assert [w.colour for w in found] == ["red", "blue", "white"]
    red, blue, white = found
    assert red.shape == WallShape.STRAIGHT
    assert red.start[0] == 0.35 and red.end[0] == 1.41 and red.start[1] == red.end[1] == 1.02
    assert blue == Wall("blue", WallShape.BENT, (1.76, 1.18), (2.29, 1.88))
    assert white == Wall("white", WallShape.EDGE, (0.0, 0.0), (2.46, 2.06))
    assert blue.as_json() == {"colour": "blue", "shape": "bent", "from": [1.76, 1.18], "to": [2.29, 1.88]}

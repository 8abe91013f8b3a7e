"""What a map pixel is: the benchmark's colour code."""

from __future__ import annotations

from enum import IntEnum

import numpy as np


class Label(IntEnum):
    FLOOR = 0
    RED = 1
    BLUE = 2
    GREEN = 3
    BROWN = 4
    YELLOW = 5
    WHITE = 6
    JAR = 7
    MUG = 8
    PADDLE = 9

    @property
    def word(self) -> str:
        return self.name.lower()


N_LABELS = len(Label)
WALL_LABELS = (Label.RED, Label.BLUE, Label.GREEN, Label.BROWN, Label.YELLOW, Label.WHITE)
OBJECT_LABELS = (Label.JAR, Label.MUG, Label.PADDLE)
OBJECTS = tuple(label.word for label in OBJECT_LABELS)  # ("jar", "mug", "paddle")

# BGR, as OpenCV reads the benchmark PNGs.
LABEL_BGR: dict[Label, tuple[int, int, int]] = {
    Label.FLOOR: (0, 0, 0),
    Label.RED: (0, 0, 255),
    Label.BLUE: (255, 0, 0),
    Label.GREEN: (0, 255, 0),
    Label.BROWN: (0, 51, 102),
    Label.YELLOW: (0, 255, 252),
    Label.WHITE: (255, 255, 255),
    Label.JAR: (255, 255, 0),
    Label.MUG: (255, 0, 255),
    Label.PADDLE: (0, 128, 128),
}

# Label -> BGR lookup table, for painting label grids.
PALETTE_BGR = np.array([LABEL_BGR[label] for label in Label], dtype=np.uint8)


def object_label(name: str) -> Label:
    """'jar' -> Label.JAR; a clear error for anything else."""
    label = Label.__members__.get(name.upper())
    if label is None or label not in OBJECT_LABELS:
        raise ValueError(f"unknown object {name!r}; expected one of {', '.join(OBJECTS)}")
    return label

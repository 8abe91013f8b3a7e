"""Where a Driver says a thing is: the four sectors of its view (and none named), the words for
them and for the labels, and how near is near. Shared by the readers of the dialog and by the LDH
task's features, which sit above them."""

from __future__ import annotations

from enum import IntEnum

from sim.core.labels import Label

NEAR_M = 0.5


class Sector(IntEnum):
    FRONT = 0
    LEFT = 1
    BEHIND = 2
    RIGHT = 3
    ANY = 4  # a label named with no direction


SECTOR_HEADING_OFFSET = (0, 2, 4, 6)  # heading steps of 45 degrees, counter-clockwise

LABEL_WORDS = {
    "red": Label.RED,
    "orange": Label.RED,
    "blue": Label.BLUE,
    "green": Label.GREEN,
    "brown": Label.BROWN,
    "wooden": Label.BROWN,
    "wood": Label.BROWN,
    "yellow": Label.YELLOW,
    "white": Label.WHITE,
    "edge": Label.WHITE,
    "jar": Label.JAR,
    "mug": Label.MUG,
    "cup": Label.MUG,
    "paddle": Label.PADDLE,
}
SECTOR_WORDS = {
    "front": Sector.FRONT,
    "ahead": Sector.FRONT,
    "facing": Sector.FRONT,
    "straight": Sector.FRONT,
    "forward": Sector.FRONT,
    "left": Sector.LEFT,
    "right": Sector.RIGHT,
    "behind": Sector.BEHIND,
    "back": Sector.BEHIND,
}

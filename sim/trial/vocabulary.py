"""The trial's closed vocabularies. The values are the strings stored in the event log.

`Move` is the wire protocol's (`robot_client.protocol`), the one move vocabulary from the rover
to the learners."""

from __future__ import annotations

from enum import StrEnum

from robot_client.protocol import Move as Move


class Role(StrEnum):
    """Who takes part: the two participants, the rover in the robot seat, the overhead camera."""

    COMMANDER = "commander"
    DRIVER = "driver"
    ROBOT = "robot"
    OVERHEAD = "overhead"


ROBOT_ROLES = (Role.DRIVER, Role.OVERHEAD)  # a rover registers as the trial's `driver` camera

PARTICIPANTS = (Role.COMMANDER, Role.DRIVER)


class Phase(StrEnum):
    """Where a trial stands."""

    WAITING = "waiting"
    LOCALIZING = "localizing"
    NAVIGATING = "navigating"
    FINISHED = "finished"
    ABORTED = "aborted"

    @property
    def running(self) -> bool:
        """The phases the trial clock runs in (unless paused)."""
        return self in (Phase.LOCALIZING, Phase.NAVIGATING)

    @property
    def over(self) -> bool:
        return self in (Phase.FINISHED, Phase.ABORTED)


class Outcome(StrEnum):
    """What became of a move: executed, bumped into something (the robot stayed), or not executed."""

    OK = "ok"
    COLLISION = "collision"
    REFUSED = "refused"


class FrameSource(StrEnum):
    DRIVER = "driver"  # the rover's front camera
    OVERHEAD = "overhead"  # the tracker camera over the table


class PoseSource(StrEnum):
    """Where a logged pose comes from."""

    SIM = "sim"  # the simulator's truth
    TRACKER = "tracker"  # the overhead camera's tracker
    ANNOTATED = "annotated"  # a person's annotation of a recording


EXPERIMENTER_PAUSE = "experimenter"


def disconnect_pause(role: Role | str) -> str:
    """The pause reason a missing seat holds the trial with."""
    return f"disconnect:{role}"

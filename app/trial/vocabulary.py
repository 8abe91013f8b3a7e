"""The trial's closed vocabularies. The values are the strings stored in the event log.

A trial's `Phase` and a move's `Outcome` are what an agent in a seat perceives too, so they are
defined with the agents' interface (`sim.agents.turns`); `Move` is the wire protocol's
(`robot_client.protocol`), the one move vocabulary from the rover to the learners."""

from __future__ import annotations

from enum import StrEnum

from robot_client.protocol import Move as Move
from sim.agents.turns import Outcome as Outcome
from sim.agents.turns import Phase as Phase


class Role(StrEnum):
    """Who takes part: the two participants, the rover in the robot seat, the overhead camera."""

    COMMANDER = "commander"
    DRIVER = "driver"
    ROBOT = "robot"
    OVERHEAD = "overhead"


ROBOT_ROLES = (Role.DRIVER, Role.OVERHEAD)  # a rover registers as the trial's `driver` camera

PARTICIPANTS = (Role.COMMANDER, Role.DRIVER)


class ServerMessage(StrEnum):
    """The `type` of each message the server sends a seat's or a watcher's socket."""

    WELCOME = "welcome"  # on joining: where the trial stands and the dialog so far
    EVENT = "event"  # one logged event, as this role may hear it
    STATUS = "status"  # the clock, seats and pauses
    ERROR = "error"  # a message refused, with a code
    MOVE_REFUSED = "move_refused"  # to the Driver: its move request refused as it came, and why
    REPLACED = "replaced"  # the seat was opened elsewhere
    BELIEF = "belief"  # the particle filter's, to watchers
    LDH_BELIEF = "ldh_belief"  # the LDH model's, to watchers


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

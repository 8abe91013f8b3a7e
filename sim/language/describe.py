"""A view in the benchmark Drivers' words: "red wall close ahead, white wall far ahead, blue wall on
my left, the coffee mug on my right".

Each label gets a clause of its own that names its side, the way Drivers write ("blue walls are on
my right", "I see a red wall ahead"), so a reader that pairs each colour with the side named in its
clause (`sim.tasks.ldh_features.mentions`) reads what the Driver saw. A label is named where it fills
at least MIN_RAYS of a view's 13 rays (objects: any ray); near where its closest ray is within
NEAR_M (the localizer's own near/far split)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from sim.core.labels import OBJECT_LABELS, Label
from sim.core.rays import RayObservation
from sim.language.sectors import NEAR_M
from sim.language.vocab import SIDE_PHRASE, Side, wall_name

MIN_RAYS = 2
CLOSE_M = 0.25  # a wall this close ahead is one the Driver is "at"
CLAIM_M = 0.3  # the target this close in view: the Driver is at it
CENTRE_RAYS = slice(4, 9)  # the 5 middle rays: about +-13 degrees
LEFT_EDGE, RIGHT_EDGE = 12, 0  # ray 0 is 39 degrees to the right


@dataclass(frozen=True)
class Seen:
    label: Label
    rays: int  # how many of the view's rays hit it
    depth: float  # metres to its closest ray


def seen(obs: RayObservation) -> list[Seen]:
    """The labels a view's valid rays hit, most rays first."""
    out = []
    for value in np.unique(obs.labels[obs.valid]):
        label = Label(int(value))
        if label == Label.FLOOR:
            continue
        hit = obs.valid & (obs.labels == value)
        out.append(Seen(label, int(hit.sum()), float(obs.depth[hit].min())))
    return sorted(out, key=lambda s: (-s.rays, s.depth))


def mentionable(obs: RayObservation) -> list[Seen]:
    return [s for s in seen(obs) if s.rays >= MIN_RAYS or s.label in OBJECT_LABELS]


class Spot(StrEnum):
    """Where the walls close round the Driver, as it says so."""

    CORNER = "corner"
    CORRIDOR = "corridor"


@dataclass(frozen=True)
class Sighting:
    """What the Driver saw from where it stands: per side looked at, what is worth naming (none:
    open floor), and whether the walls make it a corner or a corridor."""

    spot: Spot | None
    sides: dict[Side, list[Seen]]


def _clause(s: Seen, side: Side) -> str:
    distance = "close" if s.depth <= NEAR_M else "far"
    name = wall_name(s.label)
    if s.label in OBJECT_LABELS:
        return f"the {name} {SIDE_PHRASE[side]}"
    if side == Side.AHEAD:
        return f"{name} {distance} ahead"
    return f"{distance} {name} {SIDE_PHRASE[side]}"


def place(views: Mapping[Side, RayObservation]) -> Spot | None:
    """A corner or a corridor where the views say so, from how near the walls are."""
    near = {side: bool((obs.valid & (obs.depth <= NEAR_M)).sum() >= 7) for side, obs in views.items()}
    if near.get(Side.LEFT) and near.get(Side.RIGHT) and not near.get(Side.AHEAD, True):
        return Spot.CORRIDOR
    if near.get(Side.AHEAD) and (near.get(Side.LEFT) or near.get(Side.RIGHT)):
        return Spot.CORNER
    return None


def sighting(views: Mapping[Side, RayObservation | None]) -> Sighting | None:
    """What the Driver sees on each side it has looked at, ahead first; None where it can make out
    nothing."""
    readable = {side: obs for side, obs in views.items() if obs is not None and obs.problem is None}
    if not readable:
        return None
    return Sighting(place(readable), {side: mentionable(readable[side]) for side in Side if side in readable})


def describe(views: Mapping[Side, RayObservation | None]) -> str:
    """What the Driver sees on each side it has looked at, in the scripted Driver's words."""
    sight = sighting(views)
    if sight is None:
        return "i cannot make out anything in the picture"
    clauses = []
    for side, items in sight.sides.items():
        clauses += [_clause(s, side) for s in items] if items else [f"open floor {SIDE_PHRASE[side]}"]
    where = [f"i am in a {sight.spot}"] if sight.spot else []
    return ", ".join(where + clauses)


def ahead(obs: RayObservation) -> Seen | None:
    """The wall or object straight ahead (the middle rays' nearest hit)."""
    mid = np.arange(13)[CENTRE_RAYS]
    hits = [i for i in mid if obs.valid[i] and obs.labels[i] != Label.FLOOR]
    if not hits:
        return None
    i = min(hits, key=lambda k: float(obs.depth[k]))
    return Seen(Label(int(obs.labels[i])), 1, float(obs.depth[i]))


@dataclass(frozen=True)
class Glance:
    """A short look after a move: the nearest thing straight ahead, a wall close at either edge of
    the view, and the objects in view not already named."""

    front: Seen | None
    edges: list[tuple[Side, Label]]
    objects: list[Label]


def glance(obs: RayObservation) -> Glance:
    front = ahead(obs)
    edges: list[tuple[Side, Label]] = []
    for ray, side in ((LEFT_EDGE, Side.LEFT), (RIGHT_EDGE, Side.RIGHT)):
        label = Label(int(obs.labels[ray]))
        if obs.valid[ray] and label != Label.FLOOR and obs.depth[ray] <= NEAR_M:
            edges.append((side, label))
    named = {label for _, label in edges} | ({front.label} if front is not None else set())
    objects = [s.label for s in seen(obs) if s.label in OBJECT_LABELS and s.label not in named]
    return Glance(front, edges, objects)


def brief(obs: RayObservation | None) -> str:
    """A short report after a move, in the scripted Driver's words."""
    if obs is None or obs.problem is not None:
        return "i cannot see clearly"
    look = glance(obs)
    parts = []
    if look.front is not None:
        parts.append(f"{wall_name(look.front.label)} {'close' if look.front.depth <= NEAR_M else 'far'} ahead")
    parts += [f"{wall_name(label)} {SIDE_PHRASE[side]}" for side, label in look.edges]
    parts += [f"i can see the {wall_name(label)}" for label in look.objects]
    return ", ".join(parts) if parts else "open floor ahead"


def wall_close(labels: np.ndarray, depth: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """(...) of rays (..., 13): a wall or object within CLOSE_M straight ahead (the middle rays)."""
    mid = CENTRE_RAYS
    return np.asarray((valid[..., mid] & (labels[..., mid] != Label.FLOOR) & (depth[..., mid] <= CLOSE_M)).any(axis=-1))


def at_wall(obs: RayObservation) -> bool:
    """Where a walk "until the wall" ends: the next move is blocked or a wall is close ahead."""
    return obs.forward_blocked or bool(wall_close(obs.labels, obs.depth, obs.valid))


def within_reach(labels: np.ndarray, depth: np.ndarray, valid: np.ndarray, label: Label) -> np.ndarray:
    """(...) of rays (..., 13): `label` is in view within CLAIM_M."""
    return np.asarray((valid & (labels == label) & (depth <= CLAIM_M)).any(axis=-1))


def near(obs: RayObservation, label: Label) -> bool:
    """The object (or wall) `label` is in view within CLAIM_M: the Driver is at it."""
    return bool(within_reach(obs.labels, obs.depth, obs.valid, label))

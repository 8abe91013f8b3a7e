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


def _clause(s: Seen, side: Side) -> str:
    distance = "close" if s.depth <= NEAR_M else "far"
    name = wall_name(s.label)
    if s.label in OBJECT_LABELS:
        return f"the {name} {SIDE_PHRASE[side]}"
    if side == Side.AHEAD:
        return f"{name} {distance} ahead"
    return f"{distance} {name} {SIDE_PHRASE[side]}"


def place(views: Mapping[Side, RayObservation]) -> str | None:
    """ "in a corner" / "in a corridor" where the views say so, from how near the walls are."""
    near = {side: bool((obs.valid & (obs.depth <= NEAR_M)).sum() >= 7) for side, obs in views.items()}
    if near.get(Side.LEFT) and near.get(Side.RIGHT) and not near.get(Side.AHEAD, True):
        return "i am in a corridor"
    if near.get(Side.AHEAD) and (near.get(Side.LEFT) or near.get(Side.RIGHT)):
        return "i am in a corner"
    return None


def describe(views: Mapping[Side, RayObservation | None]) -> str:
    """What the Driver sees on each side it has looked at, ahead first."""
    readable = {side: obs for side, obs in views.items() if obs is not None and obs.problem is None}
    clauses = []
    for side in Side:
        if side not in readable:
            continue
        items = mentionable(readable[side])
        if items:
            clauses += [_clause(s, side) for s in items]
        else:
            clauses.append(f"open floor {SIDE_PHRASE[side]}")
    if not readable:
        return "i cannot make out anything in the picture"
    where = place(readable)
    return ", ".join(([where] if where else []) + clauses)


def ahead(obs: RayObservation) -> Seen | None:
    """The wall or object straight ahead (the middle rays' nearest hit)."""
    mid = np.arange(13)[CENTRE_RAYS]
    hits = [i for i in mid if obs.valid[i] and obs.labels[i] != Label.FLOOR]
    if not hits:
        return None
    i = min(hits, key=lambda k: float(obs.depth[k]))
    return Seen(Label(int(obs.labels[i])), 1, float(obs.depth[i]))


def brief(obs: RayObservation | None) -> str:
    """A short report after a move: what is ahead and at each edge of the view."""
    if obs is None or obs.problem is not None:
        return "i cannot see clearly"
    parts = []
    front = ahead(obs)
    if front is not None:
        parts.append(f"{wall_name(front.label)} {'close' if front.depth <= NEAR_M else 'far'} ahead")
    for ray, side in ((LEFT_EDGE, Side.LEFT), (RIGHT_EDGE, Side.RIGHT)):
        label = Label(int(obs.labels[ray]))
        if obs.valid[ray] and label != Label.FLOOR and obs.depth[ray] <= NEAR_M:
            parts.append(f"{wall_name(label)} {SIDE_PHRASE[side]}")
    named = " ".join(parts)
    parts += [
        f"i can see the {wall_name(s.label)}"
        for s in seen(obs)
        if s.label in OBJECT_LABELS and wall_name(s.label) not in named
    ]
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

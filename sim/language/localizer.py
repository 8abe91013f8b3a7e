"""A belief over the robot's pose from the dialog: a language-conditioned filter.

The belief is a log-likelihood over every (node, heading) of a maze's navigation graph. Each
Driver message multiplies it by the likelihood of the facts it states (`sim.language.lexicon`)
at each pose, read off what that pose sees (`Scene`: the 13 rays of the camera turned to the
front, left, behind and right); a Commander's question counts once the Driver answers it; a
turn the Driver reports (or agrees to make) shifts the belief's headings. Nothing here knows
the true pose: the scene is the map's, the dialog is what either seat reads.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from sim.core.geometry import HEADINGS, TABLE_HEIGHT_M, TABLE_WIDTH_M, TURN_RAD
from sim.core.labels import N_LABELS, Label
from sim.core.observations import RAY_OFFSETS
from sim.language.calibration import FITTED, Calibration, evidence
from sim.language.lexicon import (
    Distance,
    Fact,
    QuestionFacts,
    Source,
    ViewKind,
    answer,
    facts,
    is_question,
    question,
    says_no,
    turn_steps,
)
from sim.language.sectors import NEAR_M, SECTOR_HEADING_OFFSET, Sector

OPEN_M = 0.6  # a ray that travels this far sees open space (a corridor)
EDGE_M = 0.05  # a white hit this close to the table's side is the maze's edge
ROLES = ("oracle", "navigator")  # Commander, Driver: the benchmark's role names


@dataclass(frozen=True)
class Weights:
    """How much each kind of evidence counts; tuned on train and val_seen only. With a
    `calibration`, the evidence it was fitted for is scored by it instead."""

    floor: float = 0.005  # likelihood of a fact the pose does not bear out at all
    far_weight: float = 0.5  # a far hit's share, for a label named with no distance
    mismatch_weight: float = 0.25  # a near hit's share for "far", a far one's for "near"
    negation_gain: float = 3.0  # a negated label seen by a third of the rays is as unlikely as can be
    label: float = 1.0
    edge: float = 2.0
    corridor: float = 0.5
    corner: float = 0.3
    dead_end: float = 0.5
    next_to: float = 0.5
    answer: float = 0.5  # a question answered, relative to the Driver's own words
    negated: float = 0.7  # a negated fact, relative to an asserted one
    sharpness: float = 1.0  # the belief's temperature when deciding
    # A view 45 degrees off the one named counts at this share: a person's "to my left" is not a
    # camera's, and a start heading is only known to the nearest 45 degrees.
    turn_slack: float = 0.0
    calibration: Calibration | None = None


TUNED = Weights()
# Human Drivers' words (LDH): the calibration fitted on train, at the sharpness best on train; a side
# named beside its true heading is where most of train's labels that the true pose misses are seen.
HUMAN = Weights(calibration=FITTED, sharpness=2.0, turn_slack=0.3)


@dataclass(frozen=True, eq=False)
class Scene:
    """What each (node, heading) of a graph sees, per view sector (front, left, behind, right)."""

    near: np.ndarray  # (N, 8, 4, labels) share of the sector's rays hitting the label within NEAR_M
    far: np.ndarray  # (N, 8, 4, labels) ... beyond NEAR_M
    open: np.ndarray  # (N, 8, 4) share of rays reaching past OPEN_M
    close: np.ndarray  # (N, 8, 4) share of rays stopped within NEAR_M
    adjacent: np.ndarray  # (N, 8, 4, labels, labels) two labels hit by neighbouring rays
    edge: np.ndarray  # (N, 8, 4) share of rays ending on the table's border (the maze's white edge)

    @classmethod
    def from_rays(cls, labels: np.ndarray, depth: np.ndarray, nodes: np.ndarray) -> Scene:
        """From a RayTable's labels and depths, (N, 8, rays) each, cast from `nodes` (N, 2)."""
        n, headings, rays = labels.shape
        angles = np.arange(headings)[:, None] * TURN_RAD + RAY_OFFSETS[None, :]
        hit_x = nodes[:, 0, None, None] + depth * np.cos(angles)
        hit_y = nodes[:, 1, None, None] + depth * np.sin(angles)
        border = np.minimum(np.minimum(hit_x, TABLE_WIDTH_M - hit_x), np.minimum(hit_y, TABLE_HEIGHT_M - hit_y))
        edge = ((border <= EDGE_M) & (labels == Label.WHITE)).mean(axis=2)
        onehot = np.zeros((n, headings, rays, N_LABELS), dtype=np.float32)
        np.put_along_axis(onehot, labels[..., None].astype(np.int64), 1.0, axis=-1)
        near_ray = depth <= NEAR_M
        near = (onehot * near_ray[..., None]).mean(axis=2)
        far = (onehot * ~near_ray[..., None]).mean(axis=2)
        open_ = (depth > OPEN_M).mean(axis=2)
        close = near_ray.mean(axis=2)
        a, b = labels[..., :-1].astype(np.int64), labels[..., 1:].astype(np.int64)
        adjacent = np.zeros((n, headings, N_LABELS, N_LABELS), dtype=bool)
        ni, hi = np.meshgrid(np.arange(n), np.arange(headings), indexing="ij")
        for k in range(rays - 1):
            adjacent[ni, hi, a[..., k], b[..., k]] = True
        adjacent |= adjacent.transpose(0, 1, 3, 2)
        sector = np.stack([(np.arange(headings) + off) % headings for off in SECTOR_HEADING_OFFSET])  # (4, 8)
        return cls(
            near=near[:, sector.T],
            far=far[:, sector.T],
            open=open_[:, sector.T],
            close=close[:, sector.T],
            adjacent=adjacent[:, sector.T],
            edge=edge[:, sector.T],
        )

    @property
    def n(self) -> int:
        return int(self.near.shape[0])


def _over(share: np.ndarray, sectors: tuple[Sector, ...], slack: float) -> np.ndarray:
    """(N, 8) share over the sectors named: the best one for ANY, else their mean, or `slack` times
    the share one heading either way where that is more."""
    if Sector.ANY in sectors:
        return np.asarray(share.max(axis=2))
    named = share[:, :, list(sectors)].mean(axis=2)
    if not slack:  # the live Commander's weights: no headings beside to weigh on every fact
        return np.asarray(named)
    beside = np.maximum(np.roll(named, 1, axis=1), np.roll(named, -1, axis=1))
    return np.asarray(np.maximum(named, slack * beside))


def fact_share(fact: Fact, scene: Scene, w: Weights) -> np.ndarray:
    """(N, 8) in [0, 1]: how well each pose bears the fact out (before negation)."""
    if fact.kind == ViewKind.LABEL:
        assert fact.label is not None
        near, far = scene.near[..., fact.label], scene.far[..., fact.label]
        if fact.distance == Distance.NEAR:
            share = near + w.mismatch_weight * far
        elif fact.distance == Distance.FAR:
            share = w.mismatch_weight * near + far
        else:
            share = near + w.far_weight * far
        return _over(share, fact.sectors, w.turn_slack)
    if fact.kind == ViewKind.CORRIDOR:
        return _over(scene.open, fact.sectors, w.turn_slack)
    if fact.kind == ViewKind.EDGE:
        return _over(scene.edge, fact.sectors, w.turn_slack)
    close = scene.close
    if fact.kind == ViewKind.CORNER:
        return np.asarray(close[:, :, Sector.FRONT] * np.maximum(close[:, :, Sector.LEFT], close[:, :, Sector.RIGHT]))
    if fact.kind == ViewKind.DEAD_END:
        return np.asarray(close[:, :, Sector.FRONT] * close[:, :, Sector.LEFT] * close[:, :, Sector.RIGHT])
    assert fact.label is not None and fact.other is not None
    pair = scene.adjacent[..., fact.label, fact.other].astype(np.float32)
    return _over(pair, fact.sectors, w.turn_slack)


def fact_loglik(fact: Fact, scene: Scene, w: Weights) -> np.ndarray:
    """(N, 8) weighted log-likelihood of one fact at every pose."""
    share = fact_share(fact, scene, w)
    kind = evidence(fact)
    calibrated = None if w.calibration is None or kind is None else w.calibration.loglik(kind, share)
    if calibrated is not None:
        return calibrated * (w.answer if fact.source == Source.ANSWER else 1.0)
    if fact.negated:
        gain = w.negation_gain if fact.kind == ViewKind.LABEL else 1.0
        loglik = w.negated * np.log(w.floor + np.clip(1.0 - gain * share, 0.0, 1.0))
    else:
        loglik = np.log(w.floor + share)
    weight = {
        ViewKind.LABEL: w.label,
        ViewKind.EDGE: w.edge,
        ViewKind.CORRIDOR: w.corridor,
        ViewKind.CORNER: w.corner,
        ViewKind.DEAD_END: w.dead_end,
        ViewKind.NEXT_TO: w.next_to,
    }[fact.kind]
    if fact.source == Source.ANSWER:
        weight *= w.answer
    return np.asarray(weight * loglik)


class Belief:
    """The filter: log-likelihood (N, 8) of the robot's current pose given the dialog so far."""

    def __init__(self, scene: Scene, allowed: np.ndarray, weights: Weights = TUNED):
        self.scene = scene
        self.weights = weights
        self.log = np.where(np.asarray(allowed, dtype=bool)[:, None], 0.0, -np.inf) * np.ones((1, HEADINGS))
        self._question: QuestionFacts | None = None
        self.turned = 0  # heading steps turned since the start, mod 8

    def observe(self, facts: Iterable[Fact]) -> None:
        for fact in facts:
            self.log = self.log + fact_loglik(fact, self.scene, self.weights)

    def turn(self, steps: int) -> None:
        """The robot turned `steps` x 45 degrees counter-clockwise: what was heading h is h + steps."""
        self.log = np.roll(self.log, steps, axis=1)
        self.turned = (self.turned + steps) % HEADINGS

    def message(self, role: str, text: str, read: Iterable[Fact] | None = None) -> list[Fact]:
        """Update on one message of the dialog (role: oracle = Commander, navigator = Driver); a
        Driver's facts are `read` where a reader made them, the lexicon's otherwise. Returns the
        facts weighed (none for a Commander's message: its question counts when answered)."""
        if role not in ROLES:
            raise ValueError(f"unknown role {role!r}; expected one of {', '.join(ROLES)}")
        if role == "oracle":
            if is_question(text):
                self._question = question(text)
            return []
        q, self._question = self._question, None
        declined = says_no(text)
        reported = turn_steps(text)
        if reported:
            self.turn(reported)
        elif q is not None and q.turn and not declined:
            self.turn(q.turn)
        stated = list(read if read is not None else answer(q, text) if q is not None else facts(text))
        self.observe(stated)
        return stated

    def node_logits(self) -> np.ndarray:
        """(N, 8) logits at the weights' sharpness (softmax them for probabilities)."""
        return np.asarray(self.log * self.weights.sharpness)

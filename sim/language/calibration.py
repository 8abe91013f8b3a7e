"""How much a human Driver's words say about a pose, fitted on the train split's dialogs.

For each kind of evidence, the share of a fact a pose bears out (`localizer.fact_share`) is
binned, and the fact's log-likelihood at a pose is the log ratio of how often the true pose's
share falls in that bin to how often any pose's does: a red wall "to my left" where the pose's
left view is mostly red is about six times as likely as at a random pose, where none of it is
red (nor of the views 45 degrees either way) about a seventh as likely. A label named ahead is
fitted apart from one beside or behind: the view ahead reaches far and mixes colours, so a little
of it bears the label out about as well as most of it does. Negated facts and dead ends are too
rare on train to fit: the hand weights score them.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from sim.language.lexicon import Fact, ViewKind
from sim.language.sectors import Sector

SHARE_EDGES = (0.0, 1e-9, 0.15, 0.35, 0.65, 1.0 + 1e-9)  # bins: none of it, a little, ..., most of it
PRIOR = 4.0  # pseudo-facts at the reference distribution: an evidence seen a few times stays near 0


class Evidence(StrEnum):
    LABEL = "label"  # a label beside or behind: mostly the wall there, filling the view
    LABEL_AHEAD = "label_ahead"  # a label ahead: often far, a part of a mixed view
    LABEL_ANYWHERE = "label_anywhere"  # a label with no direction
    EDGE = "edge"
    CORRIDOR = "corridor"
    CORNER = "corner"
    NEXT_TO = "next_to"


_BY_KIND = {
    ViewKind.EDGE: Evidence.EDGE,
    ViewKind.CORRIDOR: Evidence.CORRIDOR,
    ViewKind.CORNER: Evidence.CORNER,
    ViewKind.NEXT_TO: Evidence.NEXT_TO,
}


def evidence(fact: Fact) -> Evidence | None:
    """The fact's kind of evidence; None where the hand weights score it."""
    if fact.negated:
        return None
    if fact.kind == ViewKind.LABEL:
        if fact.sectors == (Sector.ANY,):
            return Evidence.LABEL_ANYWHERE
        return Evidence.LABEL_AHEAD if fact.sectors == (Sector.FRONT,) else Evidence.LABEL
    return _BY_KIND.get(fact.kind)


def share_bin(share: np.ndarray) -> np.ndarray:
    return np.clip(np.searchsorted(SHARE_EDGES, share, side="right") - 1, 0, len(SHARE_EDGES) - 2)


@dataclass(frozen=True)
class Calibration:
    log_ratio: dict[Evidence, tuple[float, ...]]  # per bin of SHARE_EDGES

    def loglik(self, kind: Evidence, share: np.ndarray) -> np.ndarray | None:
        """Log-likelihood of a fact of this kind at shares `share`; None where none was fitted."""
        if kind not in self.log_ratio:
            return None
        return np.asarray(np.asarray(self.log_ratio[kind], dtype=np.float64)[share_bin(share)])


@dataclass(frozen=True)
class Record:
    """One fact a Driver stated: the share its true pose bears out, and every candidate pose's."""

    kind: Evidence
    true_share: float
    shares: np.ndarray  # every allowed pose's


def fit(records: Iterable[Record], prior: float = PRIOR) -> Calibration:
    """Per kind: log of P(bin | true pose) over P(bin | any pose), the former smoothed toward the latter."""
    by_kind: dict[Evidence, list[Record]] = defaultdict(list)
    for r in records:
        by_kind[r.kind].append(r)
    out = {}
    for kind, rows in by_kind.items():
        bins = len(SHARE_EDGES) - 1
        reference = np.mean([np.bincount(share_bin(r.shares), minlength=bins) / r.shares.size for r in rows], axis=0)
        true = np.bincount(share_bin(np.array([r.true_share for r in rows])), minlength=bins)
        stated = (true + prior * reference) / (len(rows) + prior)
        ratio = np.log(np.maximum(_pooled(stated, reference), 1e-6) / np.maximum(reference, 1e-6))
        out[kind] = tuple(round(float(v), 3) for v in ratio)
    return Calibration(out)


def _pooled(stated: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """`stated`, its ratio to `reference` made non-decreasing over the bins (pool adjacent violators):
    more of a view bearing a fact out never makes it less likely. A few dozen facts per kind leave
    dips that are noise, and a Driver naming only what fills the view would be read backwards."""
    blocks: list[list[int]] = []
    for b in range(len(stated)):
        blocks.append([b])
        while len(blocks) > 1 and _ratio(stated, reference, blocks[-2]) > _ratio(stated, reference, blocks[-1]):
            blocks[-2:] = [blocks[-2] + blocks[-1]]
    out = stated.copy()
    for block in blocks:
        if len(block) > 1:
            out[block] = reference[block] * _ratio(stated, reference, block)
    return out


def _ratio(stated: np.ndarray, reference: np.ndarray, bins: list[int]) -> float:
    return float(stated[bins].sum() / max(reference[bins].sum(), 1e-9))


# `python -m bench.ldh_calibration --benchmark PATH` (train split, rules' reading, prefix variant).
FITTED = Calibration(
    {
        Evidence.LABEL: (-1.973, -0.467, -0.378, 0.107, 1.808),
        Evidence.LABEL_AHEAD: (-1.75, 0.196, 0.774, 0.774, 0.774),
        Evidence.LABEL_ANYWHERE: (-1.508, 0.215, 0.215, 0.215, 0.228),
        Evidence.EDGE: (-1.117, -0.942, -0.942, -0.942, 1.14),
        Evidence.CORRIDOR: (-1.609, -0.074, -0.074, 0.291, 0.291),
        Evidence.CORNER: (-1.504, 0.008, 0.039, 0.039, 0.039),
        Evidence.NEXT_TO: (-0.704, -0.704, 0.464, 0.464, 0.764),
    }
)

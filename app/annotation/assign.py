"""Who annotates what: a share of a study's trials (stratified by layout) goes to two annotators,
for agreement; every other trial to one. Assignment is once per trial: a trial already in a
queue is not drawn again, so running it after more trials were recorded assigns only those."""

from __future__ import annotations

import itertools
import math
import random
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.db.models import AnnotationAssignment, Experimenter, Trial
from app.export.source import exported_trial_ids
from app.security import AccountRole

DOUBLE_SHARE = 0.2  # the paper tagged a 20 % sample


class AssignmentError(ValueError):
    """Assignment asked of too few annotators, an unknown one, or a share outside [0, 1]."""


@dataclass(frozen=True)
class Assignment:
    double: list[int]  # trial ids, each to two annotators
    single: list[int]
    queues: dict[str, list[int]]  # annotator name -> trial ids newly assigned


def sample_double(by_layout: Mapping[str, Sequence[int]], share: float, rng: random.Random) -> list[int]:
    """round(share * trials) trials, spread over layouts in proportion to their trials (largest
    remainders), drawn at random within each layout."""
    total = sum(len(v) for v in by_layout.values())
    want = round(share * total)
    quotas = {layout: share * len(ids) for layout, ids in by_layout.items()}
    counts = {layout: math.floor(q) for layout, q in quotas.items()}
    for layout in sorted(quotas, key=lambda k: (counts[k] - quotas[k], k))[: want - sum(counts.values())]:
        counts[layout] += 1
    picked = []
    for layout in sorted(by_layout):
        picked += rng.sample(sorted(by_layout[layout]), counts[layout])
    return sorted(picked)


def assign(
    db: Session, study: str, annotators: Sequence[str], layouts: Mapping[str, str], share: float, seed: int
) -> Assignment:
    """Queue the study's finished trials not yet assigned (in the open session `db`)."""
    if not 0 <= share <= 1:
        raise AssignmentError(f"the double-annotation share must be between 0 and 1, not {share}")
    ids = {}
    for name in annotators:
        account = db.scalar(select(Experimenter).where(Experimenter.name == name))
        if account is None or account.role != AccountRole.ANNOTATOR:
            raise AssignmentError(f"no annotator {name!r} (create one: robotslang admin create NAME --role annotator)")
        ids[name] = account.id
    if len(ids) < (2 if share > 0 else 1):
        raise AssignmentError("double annotation needs at least two annotators")
    taken = set(db.scalars(select(AnnotationAssignment.trial_id)))
    trials = db.scalars(select(Trial).where(Trial.id.in_(exported_trial_ids(db, study=study)))).all()
    by_layout: dict[str, list[int]] = {}
    for t in trials:
        if t.id not in taken:
            by_layout.setdefault(layouts.get(t.maze, t.maze), []).append(t.id)
    rng = random.Random(seed)
    double = sample_double(by_layout, share, rng)
    single = sorted(set().union(*by_layout.values()) - set(double)) if by_layout else []
    queues: dict[str, list[int]] = {n: [] for n in ids}
    in_turn = itertools.cycle(ids)  # a double trial goes to the next two annotators
    for trial_id in [t for t in double for _ in range(2)] + single:
        queues[next(in_turn)].append(trial_id)
    db.add_all(
        AnnotationAssignment(trial_id=t, annotator_id=ids[name]) for name, queue in queues.items() for t in queue
    )
    return Assignment(double, single, queues)

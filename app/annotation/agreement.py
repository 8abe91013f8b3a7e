"""Agreement between two annotators of the same trials: Cohen's kappa per phenomenon (a tag
given to a dialog or not), the distance in messages between their localization cuts, and the
disagreements the experimenter adjudicates."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TypedDict

from app.annotation.events import Phenomenon
from app.annotation.log import TrialAnnotations


def cohen_kappa(a: Sequence[bool], b: Sequence[bool]) -> float | None:
    """(p_o - p_e) / (1 - p_e) for two raters' yes/no answers on the same items; None where it is
    undefined (no items, or both raters gave one and the same answer throughout: p_e = 1)."""
    if len(a) != len(b):
        raise ValueError(f"the raters answered {len(a)} and {len(b)} items: kappa needs the same items")
    n = len(a)
    if n == 0:
        return None
    observed = sum(x == y for x, y in zip(a, b, strict=True)) / n
    pa, pb = sum(a) / n, sum(b) / n
    expected = pa * pb + (1 - pa) * (1 - pb)
    if expected == 1:
        return None
    return (observed - expected) / (1 - expected)


def answer_word(value: int | bool | None) -> str:
    """An answer as the adjudication asks it: a tag yes or no, a cut its message number, none a dash."""
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    return str(value)


class DisagreementRow(TypedDict):
    trial: int
    item: str
    values: dict[str, int | bool]
    adjudicated: int | bool | None


class CutDistance(TypedDict):
    per_trial: dict[str, int]  # trial id -> messages between the two cuts
    mean: float | None
    max: int | None
    exact_share: float | None


class AgreementNumbers(TypedDict):
    double_annotated_trials: int
    kappa: dict[str, float | None]  # per tag
    cut_distance: CutDistance
    disagreements: list[DisagreementRow]


def agreement(annotations: Mapping[int, TrialAnnotations], names: Mapping[int, str]) -> AgreementNumbers:
    """Over the trials two annotators have submitted (the first two, by account id, where more
    did): kappa per phenomenon and per free tag, cut distances, and the disagreements."""
    pairs: dict[int, tuple[int, int]] = {}
    for trial_id, t in sorted(annotations.items()):
        done = sorted(i for i, a in t.by_annotator.items() if a.submitted)
        if len(done) >= 2:
            pairs[trial_id] = (done[0], done[1])
    tags = [str(p) for p in Phenomenon]
    tags += sorted({tag for t in pairs for i in pairs[t] for tag in annotations[t].by_annotator[i].tags} - set(tags))

    def disagreement(trial_id: int, item: str, x: int | bool, y: int | bool) -> DisagreementRow:
        """The pair's two values of an item they differ on, beside the experimenter's (if any)."""
        first, second = pairs[trial_id]
        values = {names[first]: x, names[second]: y}
        return {
            "trial": trial_id,
            "item": item,
            "values": values,
            "adjudicated": annotations[trial_id].adjudicated.get(item),
        }

    kappa: dict[str, float | None] = {}
    disagreements: list[DisagreementRow] = []
    for tag in tags:
        a = [tag in annotations[t].by_annotator[pairs[t][0]].tags for t in pairs]
        b = [tag in annotations[t].by_annotator[pairs[t][1]].tags for t in pairs]
        kappa[tag] = cohen_kappa(a, b)
        disagreements += [disagreement(t, tag, x, y) for t, x, y in zip(pairs, a, b, strict=True) if x != y]
    distances: dict[int, int] = {}
    for trial_id, (first, second) in pairs.items():
        by = annotations[trial_id].by_annotator
        cut_a, cut_b = by[first].cut, by[second].cut
        if cut_a is None or cut_b is None:
            continue
        distances[trial_id] = abs(cut_a - cut_b)
        if cut_a != cut_b:
            disagreements.append(disagreement(trial_id, "cut", cut_a, cut_b))
    values = list(distances.values())
    return {
        "double_annotated_trials": len(pairs),
        "kappa": kappa,
        "cut_distance": {
            "per_trial": {str(t): d for t, d in distances.items()},
            "mean": sum(values) / len(values) if values else None,
            "max": max(values) if values else None,
            "exact_share": sum(d == 0 for d in values) / len(values) if values else None,
        },
        "disagreements": sorted(disagreements, key=lambda d: (d["trial"], d["item"])),
    }

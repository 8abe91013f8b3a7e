"""Folds split by physical layout, as the paper split its data: no layout in two folds.

`robotslang export all --format ndh --study NAME --folds train:val:test=70:15:15 --seed S` draws each
layout of the study's trials into one fold, as near the shares (counted in layouts) as whole layouts
allow, and saves the split in the data directory (`folds/<study>.json`). Later exports reuse it:
layouts already split keep their fold, and only a layout new since then is drawn, so a model trained
on one export's train fold never meets its test layouts in the next.
"""

from __future__ import annotations

import json
import random
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

from sim.tasks.benchmark import Split

ALIASES = {"val": Split.VAL_SEEN}  # the and the paper's short name for val_seen
DEFAULT_SHARES = "train:val:test=70:15:15"


class FoldError(ValueError):
    pass


@dataclass(frozen=True)
class FoldShares:
    shares: dict[Split, float]  # each fold's share of the layouts, summing to 1

    @classmethod
    def parse(cls, text: str) -> FoldShares:
        """`train:val:test=70:15:15` (any positive numbers; `val` is `val_seen`)."""
        names, sep, numbers = text.partition("=")
        folds, weights = names.split(":"), numbers.split(":")
        if not sep or len(folds) != len(weights):
            raise FoldError(f"--folds {text!r}: expected names and shares, e.g. {DEFAULT_SHARES}")
        try:
            splits = [ALIASES.get(name.strip(), None) or Split(name.strip()) for name in folds]
            values = [float(w) for w in weights]
        except ValueError:
            raise FoldError(f"--folds {text!r}: folds are train, val (val_seen) and test, shares numbers") from None
        if len(set(splits)) != len(splits) or any(v < 0 for v in values) or sum(values) <= 0:
            raise FoldError(f"--folds {text!r}: each fold once, shares not negative, some share above 0")
        total = sum(values)
        return cls({s: v / total for s, v in zip(splits, values, strict=True)})

    def __str__(self) -> str:
        return ":".join(self.shares) + "=" + ":".join(f"{round(v * 100, 2):g}" for v in self.shares.values())


def draw(
    layouts: Iterable[str], shares: FoldShares, seed: int, kept: Mapping[str, str] | None = None
) -> dict[str, str]:
    """Each layout -> its fold. `kept` layouts keep theirs; the others, in an order drawn from `seed`,
    each go to the fold furthest below its share of the layouts so far (ties: the larger share)."""
    folds = dict(kept or {})
    new = sorted(set(layouts) - set(folds))
    random.Random(seed).shuffle(new)
    for layout in new:
        counts = {s: sum(1 for f in folds.values() if f == s) for s in shares.shares}
        total = len(folds) + 1
        deficit = {s: share * total - counts[s] for s, share in shares.shares.items()}
        fold = max(shares.shares, key=lambda s: (deficit[s], shares.shares[s]))
        folds[layout] = str(fold)
    return folds


@dataclass(frozen=True)
class SavedFolds:
    """A study's split, as saved in `<data_dir>/folds/<study>.json`."""

    path: Path

    @classmethod
    def of(cls, data_dir: Path, study: str) -> SavedFolds:
        return cls(Path(data_dir) / "folds" / f"{study}.json")

    def load(self) -> tuple[FoldShares, int, dict[str, str]] | None:
        """The saved shares, seed and layouts' folds; None where the study has no split yet."""
        if not self.path.exists():
            return None
        saved = json.loads(self.path.read_text())
        return FoldShares.parse(saved["shares"]), int(saved["seed"]), dict(saved["layouts"])

    def preview(self, layouts: Iterable[str]) -> dict[str, str]:
        """What `split` would give with the saved shares and seed (the default ones where there is no
        split yet), saving nothing: the study report's folds."""
        shares, seed, kept = self.load() or (FoldShares.parse(DEFAULT_SHARES), 0, {})
        return draw(layouts, shares, seed, kept)

    def split(self, layouts: Iterable[str], shares: FoldShares, seed: int) -> dict[str, str]:
        """The saved split, extended to `layouts` new since, and saved again. Asking for other shares
        or another seed than the saved split's is refused: the split is the benchmark's, once."""
        saved = self.load()
        kept: dict[str, str] = {}
        if saved is not None:
            if (str(saved[0]), saved[1]) != (str(shares), seed):
                raise FoldError(
                    f"{self.path} already splits this study with --folds {saved[0]} --seed {saved[1]}; "
                    f"pass those (or delete the file to draw a new split, which changes every fold)"
                )
            kept = saved[2]
        folds = draw(layouts, shares, seed, kept)
        if folds != kept:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            document = {"shares": str(shares), "seed": seed, "layouts": dict(sorted(folds.items()))}
            self.path.write_text(json.dumps(document, indent=1) + "\n")
        return folds

"""Folds by layout (`app.export.folds`): each layout in one fold, near the shares asked, saved once
and reused, so a later export never moves a layout to another fold."""

from __future__ import annotations

import json

import pytest

from app.export.folds import FoldError, FoldShares, SavedFolds, draw


def test_shares_parse_with_val_for_val_seen_and_refuse_what_is_not_a_split():
    shares = FoldShares.parse("train:val:test=70:15:15")
    assert {str(k): round(v, 3) for k, v in shares.shares.items()} == {"train": 0.7, "val_seen": 0.15, "test": 0.15}
    assert FoldShares.parse(str(shares)) == shares
    for bad in ("train:test=70", "train:dev=50:50", "train:train=50:50", "train:test=-1:2", "70:30"):
        with pytest.raises(FoldError):
            FoldShares.parse(bad)


def test_every_layout_goes_to_one_fold_near_its_share_and_the_seed_decides_which():
    layouts = [f"L{i:03d}" for i in range(115)]
    shares = FoldShares.parse("train:val:test=70:15:15")
    folds = draw(layouts, shares, seed=1)
    assert sorted(folds) == layouts
    counts = {f: list(folds.values()).count(f) for f in ("train", "val_seen", "test")}
    assert counts == {"train": 81, "val_seen": 17, "test": 17}, counts  # 80.5 / 17.25 / 17.25 in whole layouts
    assert draw(layouts, shares, seed=1) == folds
    assert draw(layouts, shares, seed=2) != folds


def test_a_saved_split_is_reused_and_only_new_layouts_are_drawn(tmp_path):
    shares = FoldShares.parse("train:val:test=60:20:20")
    saved = SavedFolds.of(tmp_path, "pilot")
    first = saved.split([f"L{i}" for i in range(10)], shares, seed=5)
    on_disk = json.loads((tmp_path / "folds" / "pilot.json").read_text())
    assert on_disk == {"shares": "train:val_seen:test=60:20:20", "seed": 5, "layouts": dict(sorted(first.items()))}
    later = saved.split([f"L{i}" for i in range(14)], shares, seed=5)
    assert {k: later[k] for k in first} == first, "a layout keeps its fold"
    assert len(later) == 14 and saved.preview([f"L{i}" for i in range(14)]) == later
    with pytest.raises(FoldError, match="--seed 5"):
        saved.split(["L1"], shares, seed=6)

"""`experiment ndh --feedbacks/--ablations`: a subset of the protocol's configurations, and the
report's tests over only the pairs that subset holds."""

from __future__ import annotations

import json

import numpy as np
import pytest

from models.experiment import experiment_grid
from models.report import write_report
from sim.core.metrics import write_csv
from tests.models.helpers import rows


def test_the_default_grid_is_the_whole_protocol():
    grid = experiment_grid(["baseline", "improved"], ["teacher", "student"], ["none", "vision", "language"], [0, 1, 2])
    assert len(grid) == 2 * 2 * 3 * 3
    assert grid[0] == ("baseline", "teacher", "none", 0) and grid[-1] == ("improved", "student", "language", 2)


def test_a_subset_runs_only_its_configurations_in_protocol_order():
    grid = experiment_grid(["improved"], ["student"], ["language", "none"], [0, 1])
    assert grid == [
        ("improved", "student", "none", 0),
        ("improved", "student", "none", 1),
        ("improved", "student", "language", 0),
        ("improved", "student", "language", 1),
    ]


@pytest.mark.parametrize(("feedbacks", "ablations"), [(["student"], ["full"]), ([], ["none"]), (["dagger"], ["none"])])
def test_an_unknown_or_empty_selection_is_refused(feedbacks, ablations):
    with pytest.raises(ValueError, match="expected"):
        experiment_grid(["improved"], feedbacks, ablations, [0])


def test_the_report_of_a_subset_tests_only_the_pairs_it_holds(tmp_path):
    rng = np.random.default_rng(2)
    base = rng.uniform(2.0, 5.0, 30)
    for split in ("val_seen", "test"):
        results = rows(split, "stop", base + 1.0) + rows(split, "random", base + 0.8)
        for seed in (0, 1, 2):
            results += rows(split, "improved/student/none", base - 1.0 + rng.normal(0, 0.1, 30), seed=seed)
            results += rows(split, "improved/student/language", base + rng.normal(0, 0.1, 30), seed=seed)
        write_csv(tmp_path / "results" / f"{split}.csv", results)

    text = write_report(tmp_path).read_text()

    for name in ("significance.json", "significance_seeds.json"):
        tests = json.loads((tmp_path / name).read_text())
        for split in ("val_seen", "test"):
            assert {(c["a"], c["b"]) for c in tests[split]} == {("improved/student/none", "improved/student/language")}
            td = next(c for c in tests[split] if c["metric"] == "td")
            assert td["significant"]
    ablation = next(ln for ln in text.splitlines() if ln.startswith("| improved: Student forcing, language-blind"))
    assert ablation.count("*") == 4  # TD and OTD on both splits
    assert "Teacher forcing" not in text and "baseline/" not in text

"""`report ndh` from an experiment folder: tables with significance marks, tests, plots."""

from __future__ import annotations

import json

import numpy as np
import pytest

from models.experiment import choose_iters
from models.report import write_report
from sim.core.metrics import write_csv
from tests.models.helpers import rows


@pytest.fixture
def experiment(tmp_path):
    rng = np.random.default_rng(0)
    base = rng.uniform(2.0, 5.0, 30)
    for split in ("val_seen", "test"):
        results = rows(split, "stop", base + 1.0) + rows(split, "random", base + 0.8)
        results += rows(split, "baseline/student/none", base - 0.2 * (np.arange(30) % 3 == 0))
        results += rows(split, "baseline/student/language", base + 1.0 + rng.normal(0, 0.1, 30))  # clearly worse
        results += rows(split, "baseline/student/vision", base + rng.normal(0, 0.5, 30))
        results += rows(split, "baseline/teacher/none", base + rng.normal(0, 0.5, 30))
        results += rows(split, "improved/student/none", base - 1.0 + rng.normal(0, 0.1, 30))  # clearly better
        results += rows(split, "improved/teacher/none", base + rng.normal(0, 0.5, 30))
        write_csv(tmp_path / "results" / f"{split}.csv", results)
    hist = tmp_path / "runs" / "baseline" / "student-none" / "seed0" / "val" / "history.json"
    hist.parent.mkdir(parents=True)
    hist.write_text(
        json.dumps([{"iteration": 10, "loss": 1.0, "val_td": 4.0}, {"iteration": 20, "loss": 0.9, "val_td": 3.5}])
    )
    return tmp_path


def test_report_marks_the_significantly_worse_ablation_only(experiment):
    path = write_report(experiment)
    text = path.read_text()
    line = next(ln for ln in text.splitlines() if ln.startswith("| baseline: Student forcing, language-blind"))
    assert line.count("*") == 4  # TD and OTD on both splits
    full = next(ln for ln in text.splitlines() if ln.startswith("| baseline: Student forcing, vision + language"))
    assert "*" not in full
    assert "| Immediate Stop |" in text and "| Random |" in text
    tests = json.loads((experiment / "significance.json").read_text())
    pairs = {(c["a"], c["b"]) for c in tests["test"]}
    assert ("baseline/student/none", "baseline/student/language") in pairs
    assert ("baseline/student/none", "baseline/teacher/none") in pairs
    assert ("improved/student/none", "baseline/student/none") in pairs
    better = next(ln for ln in text.splitlines() if ln.startswith("| improved: Student forcing, vision + language"))
    assert better.count("‡") == 4  # TD and OTD on both splits, on the variant's row
    same = next(ln for ln in text.splitlines() if ln.startswith("| improved: Teacher forcing, vision + language"))
    assert "‡" not in same
    for png in ("td_distribution.png", "learning_curves.png"):
        assert (experiment / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_report_gives_each_seed_and_tests_across_seeds(tmp_path):
    rng = np.random.default_rng(1)
    base = rng.uniform(2.0, 5.0, 30)
    results = []
    for seed, shift in enumerate((-1.0, -0.9, -1.1)):  # improved beats the baseline on every seed
        results += rows("val_seen", "baseline/student/none", base + rng.normal(0, 0.1, 30), seed=seed)
        results += rows("val_seen", "improved/student/none", base + shift + rng.normal(0, 0.1, 30), seed=seed)
    write_csv(tmp_path / "results" / "val_seen.csv", results)
    text = write_report(tmp_path).read_text()
    seed_rows = [ln for ln in text.splitlines() if ln.startswith("| val_seen | improved/student/none | ")]
    assert [ln.split(" | ")[2] for ln in seed_rows] == ["0", "1", "2"]
    assert all(ln.endswith("| 10.0 | 1.00 |") for ln in seed_rows)  # 10 steps each, under the cap: stopped
    across = json.loads((tmp_path / "significance_seeds.json").read_text())["val_seen"]
    td = next(c for c in across if c["metric"] == "td" and c["a"] == "improved/student/none")
    assert td["unit"] == "seed" and td["n"] == 3 and td["significant"]
    assert "## Tests across seeds" in text


def test_report_without_results_names_the_folder(tmp_path):
    with pytest.raises(FileNotFoundError, match="results"):
        write_report(tmp_path)


def test_iterations_are_sized_to_the_budget():
    costs = {"teacher": 0.5, "student": 0.7}
    one = choose_iters(costs, n_models=1, n_seeds=3, budget_s=7200, workers=1)
    assert one == int((7200 / (1.2 * 3 * 3) - 4) / 1.75)
    assert choose_iters(costs, n_models=2, n_seeds=3, budget_s=7200, workers=1) < one
    assert choose_iters(costs, n_models=1, n_seeds=3, budget_s=7200, workers=2) > one

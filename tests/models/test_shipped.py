"""The Driver shipped in the package is what `eval ndh` scores when no checkpoint is given."""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from app.cli import root
from models.shipped import SHIPPED_CHECKPOINT


@pytest.mark.slow
def test_eval_without_a_checkpoint_scores_the_shipped_driver(benchmark_path, tmp_path):
    csv = tmp_path / "val_seen.csv"
    result = CliRunner().invoke(
        root,
        [
            "eval",
            "ndh",
            "--benchmark",
            str(benchmark_path),
            "--split",
            "val_seen",
            "--json",
            "--per-instance",
            str(csv),
        ],
    )
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["n"] == 76 and list(report["agents"]) == ["seq2seq-improved-student-none"]
    driver = report["agents"]["seq2seq-improved-student-none"]
    assert driver["steps_mean"] < 120 and driver["sr"] > 0  # it stops by itself, and finds goals so
    assert len(csv.read_text().splitlines()) == 1 + 76  # a row per instance
    explicit = CliRunner().invoke(
        root,
        [
            "eval",
            "ndh",
            "--benchmark",
            str(benchmark_path),
            "--split",
            "val_seen",
            "--json",
            "--checkpoint",
            str(SHIPPED_CHECKPOINT),
        ],
    )
    assert json.loads(explicit.stdout) == report  # the default is exactly the shipped file

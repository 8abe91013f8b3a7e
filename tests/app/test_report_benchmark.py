"""`robotslang report study --benchmark PATH` alone: the public benchmark's messages and words
per dialog, computed from its NDH files, printed beside the paper's (28 messages, 200 words)."""

from __future__ import annotations

import json
import statistics

import pytest

from tests.app.live import cli

pytestmark = pytest.mark.slow  # the first grouping of the benchmark's maps by layout takes seconds


def test_benchmark_dialog_lengths_beside_the_papers(benchmark_path, tmp_path):
    made = cli(
        "report",
        "study",
        "--benchmark",
        str(benchmark_path),
        "--out",
        str(tmp_path),
        env={"ROBOTSLANG_DATA_DIR": str(tmp_path / "var")},
    )
    assert made.returncode == 0, made.stderr
    # By hand from the files: a run's dialog is its longest NDH instance's (up to the last target).
    longest: dict[str, list] = {}
    for split in ("train", "val_seen", "test"):
        for inst in json.loads((benchmark_path / "NDH-data" / f"{split}.json").read_text()):
            run = inst["scan"].split("/")[1]
            if len(inst["dialog_history"]) > len(longest.get(run, [])):
                longest[run] = inst["dialog_history"]
    messages = statistics.fmean(len(d) for d in longest.values())
    words = statistics.fmean(sum(len(t["message"].split()) for t in d) for d in longest.values())
    numbers = json.loads((tmp_path / "benchmark.json").read_text())
    assert numbers["messages_per_dialog"] == messages and numbers["words_per_dialog"] == words
    assert numbers["counts"]["trials"] == len(longest)
    assert round(messages) == 28 and abs(words - 200) < 10  # the paper's 28 messages and 200 words
    assert f"| messages per dialog | {messages:.1f} | 28 |" in made.stdout
    assert f"| words per dialog | {words:.1f} | 200 |" in made.stdout
    assert "duration_minutes: the benchmark's files carry no timestamps" in made.stdout
    assert sum(f["instances"] for f in numbers["folds"]) == sum(
        len(json.loads((benchmark_path / "NDH-data" / f"{s}.json").read_text())) for s in ("train", "val_seen", "test")
    )

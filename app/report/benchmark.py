"""What the public benchmark's files give of the paper's dataset section, beside the paper's
numbers: each run's dialog is its longest NDH instance's (the dialog up to the last target)."""

from __future__ import annotations

from pathlib import Path
from typing import TypedDict

from app.report.study import DialogNumbers, dialog_numbers
from sim.tasks.benchmark import Benchmark, Split
from sim.tasks.layouts import FoldCount, fold_counts


class Paper(TypedDict):
    messages_per_dialog: int
    words_per_dialog: int
    duration_minutes: float
    phenomena: dict[str, float]  # share of the dialogs showing each


class BenchmarkCounts(TypedDict):
    trials: int
    layouts: int


class BenchmarkNumbers(TypedDict):
    """benchmark.json of `report study --benchmark`."""

    source: str
    counts: BenchmarkCounts
    messages_per_dialog: float | None
    words_per_dialog: float | None
    dialog: DialogNumbers
    folds: list[FoldCount]
    paper: Paper
    not_in_files: dict[str, str]  # a number of the paper -> why the files cannot give it


# The paper's dataset section (Banerjee, Thomason, Corso, CoRL 2020), as issue 25 quotes it.
PAPER: Paper = {
    "messages_per_dialog": 28,
    "words_per_dialog": 200,
    "duration_minutes": 6.5,
    "phenomena": {
        "needs_history": 0.530,
        "communication_repair": 0.265,
        "relocalization_repair": 0.147,
        "surrender_control": 0.118,
        "perceptual_differences": 0.029,
    },
}
NOT_IN_FILES = {
    "duration_minutes": "the benchmark's files carry no timestamps",
    "participants": "the benchmark's files name no participants or teams",
    "moves": "the benchmark's files carry the dialogs and poses, not the moves made",
    "phenomena": "the benchmark's files carry no phenomenon tags",
}


def benchmark_numbers(path: Path, layout_of: dict[str, str]) -> BenchmarkNumbers:
    bench = Benchmark(path)
    splits = {str(s): bench.split(s) for s in Split}
    longest: dict[str, tuple[tuple[str, str], ...]] = {}
    for instances in splits.values():
        for inst in instances:
            if len(inst.dialog) > len(longest.get(inst.run, ())):
                longest[inst.run] = inst.dialog
    dialogs = [longest[run] for run in sorted(longest)]
    numbers = dialog_numbers(dialogs)
    return {
        "source": str(path),
        "counts": {"trials": len(longest), "layouts": len({layout_of.get(r, r) for r in longest})},
        "messages_per_dialog": numbers["messages_per_dialog"],
        "words_per_dialog": numbers["words_per_dialog"],
        "dialog": numbers,
        "folds": fold_counts({s: [i.run for i in insts] for s, insts in splits.items()}, layout_of),
        "paper": PAPER,
        "not_in_files": NOT_IN_FILES,
    }

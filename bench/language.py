"""How well the dialog agents read people: the frozen gold set of human turns, scored.

    python -m bench.language --benchmark PATH [--split val_seen|test] [--json]

The gold set (`bench/language_gold/`, guide in docs/language_gold.md) holds hand-annotated
Commander and Driver turns of the benchmark's recorded val_seen and test dialogs, by name and
text hash only: the texts are read from the benchmark here, and a turn whose text no longer
hashes as annotated stops the run. The set's own hashes are checked before anything is scored,
so an edited set cannot be scored (errata go in a second file, counted both ways).

Commander turns are scored as programs (exact match in order, clause F1 as multisets); Driver
turns as fact sets (fact F1). `commander` / `driver` are the trained readers as the agents use
them (`sim.language.understanding`; the dialog Commander reads a Driver by the rules unless seated
with the trained reader, docs/model_card_language.md); `baseline` is the rules alone
(`instructions.parse`, and `lexicon` as the Commander agent reads a Driver). The readers are used
alone: the rules as a fallback below a reader's confidence scored no better (model card).
understand_p95_ms: the agents' time to understand one turn; model_mb: the resident memory that
loading the readers and reading the set added. Develop on val_seen; score test once per release.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import resource
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bench.report import percentile, rss_mb
from sim.language import instructions as ins
from sim.language import lexicon
from sim.language.meaning import Clause, FactForm, Program, Score, facts_of, program_of, score_facts, score_programs
from sim.language.reader import Reader, Role, shipped
from sim.language.understanding import Understanding
from sim.tasks.benchmark import Benchmark, Split, text_hash

GOLD_DIR = Path(__file__).parent / "language_gold"
# The frozen set: sha256 of each file, committed before the code it judges changes.
GOLD_SHA256 = {
    "commander.jsonl": "bf0af40a69b51104347d3966a2bdc597aa267ff1e005e39c16cd1868581f8672",
    "driver.jsonl": "f783e9c75c6bd1270d19f2f1355041b5f07ee16cfeaa3b87da30bc0690c3d672",
}
GOLD_SPLITS = (Split.VAL_SEEN, Split.TEST)


class GoldError(ValueError):
    """The gold set is not the frozen one, or does not match the benchmark."""


@dataclass(frozen=True)
class RecordedTurn:
    """One recorded turn of a run's dialog, with what the speaker's partner had heard before it."""

    id: str  # SPLIT/RUN/INDEX
    role: str  # oracle (Commander) or navigator (Driver)
    text: str
    before: tuple[tuple[str, str], ...]

    def asked(self) -> str | None:
        """The Commander's latest question since the Driver last spoke (what a Driver turn answers)."""
        return lexicon.asked((role == "oracle", text) for role, text in self.before)

    def previous(self) -> tuple[str, str] | None:
        """The turn before, as the agents' reader takes it ("c" Commander, "d" Driver)."""
        if not self.before:
            return None
        role, text = self.before[-1]
        return ("c" if role == "oracle" else "d", text)


def check_frozen(directory: Path = GOLD_DIR) -> None:
    for name, want in GOLD_SHA256.items():
        got = hashlib.sha256((directory / name).read_bytes()).hexdigest()
        if got != want:
            raise GoldError(f"{directory / name}: sha256 {got}, the frozen set is {want}; the gold set is never edited")


def turns(benchmark: Benchmark, split: str) -> dict[str, RecordedTurn]:
    out: dict[str, RecordedTurn] = {}
    for run, dialog in benchmark.dialogs(split).items():
        for index, (role, text) in enumerate(dialog):
            name = f"{split}/{run}/{index}"
            out[name] = RecordedTurn(name, role, text, dialog[:index])
    return out


def _records(path: Path) -> Iterator[dict[str, Any]]:
    with path.open() as f:
        for line in f:
            if line.strip():
                yield json.loads(line)


def gold(
    benchmark: Benchmark, split: str, directory: Path = GOLD_DIR
) -> tuple[list[tuple[RecordedTurn, Program]], list[tuple[RecordedTurn, frozenset[FactForm]]]]:
    """The gold set's Commander programs and Driver facts of one split, with their turns."""
    if split not in GOLD_SPLITS:
        raise GoldError(f"the gold set holds {', '.join(GOLD_SPLITS)} turns, not {split}")
    check_frozen(directory)
    recorded = turns(benchmark, split)

    def turn(record: dict[str, Any], role: str) -> RecordedTurn | None:
        if not record["id"].startswith(f"{split}/"):
            return None
        found = recorded.get(record["id"])
        if found is None or found.role != role or text_hash(found.text) != record["text_sha256"]:
            raise GoldError(f"{record['id']}: not the {role} turn the gold set annotated (benchmark changed?)")
        return found

    commander = [
        (t, tuple(Clause.from_json(c) for c in r["program"]))
        for r in _records(directory / "commander.jsonl")
        if (t := turn(r, "oracle")) is not None
    ]
    driver = [
        (t, frozenset(FactForm.from_json(f) for f in r["facts"]))
        for r in _records(directory / "driver.jsonl")
        if (t := turn(r, "navigator")) is not None
    ]
    return commander, driver


def rules_program(turn: RecordedTurn) -> Program:
    return program_of(ins.parse(turn.text))


def rules_facts(turn: RecordedTurn) -> frozenset[FactForm]:
    return facts_of(turn.text, turn.asked())


def _figures(commander: Score, driver: Score) -> dict[str, Any]:
    return {
        "commander": {
            "exact_match": round(commander.exact_match, 4),
            "clause_f1": round(commander.f1, 4),
            "turns": commander.turns,
        },
        "driver": {"fact_f1": round(driver.f1, 4), "turns": driver.turns},
    }


def evaluate(benchmark: Benchmark, split: str, understanding: Understanding) -> dict[str, Any]:
    """An understanding against the gold set, with the rules alone beside it (`baseline`)."""
    commander, driver = gold(benchmark, split)
    baseline = _figures(
        score_programs((rules_program(t), want) for t, want in commander),
        score_facts((rules_facts(t), want) for t, want in driver),
    )
    times: list[float] = []
    programs, facts = [], []
    for t, want in commander:
        start = time.perf_counter()
        programs.append((understanding.program(t.text, t.previous()).meaning, want))
        times.append(time.perf_counter() - start)
    for t, wanted in driver:
        start = time.perf_counter()
        facts.append((understanding.facts(t.text, t.previous(), t.asked()).meaning, wanted))
        times.append(time.perf_counter() - start)
    return {
        **_figures(score_programs(programs), score_facts(facts)),
        "baseline": baseline,
        "understand_p95_ms": round(1000 * percentile(times, 95), 3) if times else 0.0,
        "split": split,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--benchmark", default=os.environ.get("ROBOTSLANG_BENCHMARK"), help="the benchmark's folder")
    parser.add_argument("--split", default=Split.VAL_SEEN.value, choices=[s.value for s in GOLD_SPLITS])
    parser.add_argument("--json", action="store_true", help="print the figures as JSON on the last line")
    parser.add_argument(
        "--readers", type=Path, default=None, help="a `train language` output folder; default the shipped readers"
    )
    args = parser.parse_args(argv)
    if not args.benchmark:
        parser.error("--benchmark PATH (or ROBOTSLANG_BENCHMARK) is required")
    bench = Benchmark(args.benchmark)
    before_mb = rss_mb(os.getpid())
    readers = (
        (Reader(args.readers / "commander.npz"), Reader(args.readers / "driver.npz"))
        if args.readers
        else (shipped(Role.COMMANDER), shipped(Role.DRIVER))
    )
    figures = evaluate(bench, args.split, Understanding(*readers))
    figures["model_mb"] = round(rss_mb(os.getpid()) - before_mb, 1)  # the readers' weights, and what reading kept
    print(
        f"load average {' '.join(f'{v:.2f}' for v in os.getloadavg())}; peak RSS {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024} MB",
        file=sys.stderr,
    )
    if args.json:
        print(json.dumps(figures))
    else:
        for name in ("commander", "driver", "baseline"):
            print(f"{name}: {figures[name]}")
        print(
            f"understand p95 {figures['understand_p95_ms']} ms, model {figures['model_mb']} MB, split {figures['split']}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())

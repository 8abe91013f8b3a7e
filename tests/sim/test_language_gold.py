"""The gold set of human turns: frozen, tied to the benchmark's texts, and scored as bench.language says."""

from __future__ import annotations

import json
import shutil

import pytest

from bench import language
from sim.language import instructions as ins
from sim.language.meaning import Clause, FactForm, FactKind, Op, facts_of, program_of, score_facts, score_programs
from sim.tasks.benchmark import Benchmark


def test_the_gold_set_is_the_frozen_one():
    language.check_frozen()


def test_an_edited_gold_set_is_refused(tmp_path):
    for name in language.GOLD_SHA256:
        shutil.copy(language.GOLD_DIR / name, tmp_path / name)
    lines = (tmp_path / "commander.jsonl").read_text().splitlines()
    record = json.loads(lines[0])
    record["program"] = [{"op": "unclear"}]
    (tmp_path / "commander.jsonl").write_text("\n".join([json.dumps(record), *lines[1:]]) + "\n")
    with pytest.raises(language.GoldError, match="never edited"):
        language.check_frozen(tmp_path)


def test_every_annotation_is_in_the_guides_forms():
    for name, key, form in (("commander.jsonl", "program", Clause), ("driver.jsonl", "facts", FactForm)):
        for line in (language.GOLD_DIR / name).read_text().splitlines():
            record = json.loads(line)
            assert set(record) == {"id", "text_sha256", key, "annotator", "note"}
            for item in record[key]:
                form.from_json(item)  # raises on an op or field the guide does not have


def test_it_holds_the_turns_the_issue_asks_for_and_they_are_the_benchmarks(benchmark_path):
    bench = Benchmark(benchmark_path)
    commander = driver = 0
    for split in language.GOLD_SPLITS:
        programs, facts = language.gold(bench, split)  # raises if a text no longer hashes as annotated
        commander += len(programs)
        driver += len(facts)
        assert all(turn.role == "oracle" for turn, _ in programs)
        assert all(turn.role == "navigator" for turn, _ in facts)
    assert commander >= 400 and driver >= 300


def test_the_train_split_is_not_in_the_gold_set(benchmark_path):
    with pytest.raises(language.GoldError, match="not train"):
        language.gold(Benchmark(benchmark_path), "train")


def test_a_clause_takes_exactly_its_fields():
    assert Clause.from_json({"op": "turn", "eighths": -4}) == Clause(Op.TURN, (4,))  # around is around
    assert Clause.from_json({"op": "forward", "steps": None, "until": None}) == Clause(Op.FORWARD, (None, "wall"))
    with pytest.raises(ValueError, match="turn takes exactly eighths"):
        Clause.from_json({"op": "turn", "eighths": 2, "side": "left"})
    with pytest.raises(ValueError, match="answer takes exactly value"):
        FactForm.from_json({"kind": "answer"})


def test_the_rules_reading_in_the_gold_form():
    program = program_of(ins.parse("turn right at the red wall, then go forward 3 steps"))
    assert program == (
        Clause.of(Op.FORWARD, steps=None, until="red"),
        Clause.of(Op.TURN, eighths=-2),
        Clause.of(Op.FORWARD, steps=3, until=None),
    )
    said = facts_of("yes", "is there a red wall on your left?")
    assert FactForm.of(FactKind.ANSWER, value="yes") in said
    assert FactForm.of(FactKind.LABEL, label="red", side="left", distance="any", negated=False) in said


def test_scores_count_order_for_exact_match_and_multisets_for_f1():
    left, right = Clause.of(Op.TURN, eighths=2), Clause.of(Op.TURN, eighths=-2)
    score = score_programs([((left, right), (right, left)), ((), ())])
    assert (score.exact_match, score.f1) == (0.5, 1.0)
    yes = FactForm.of(FactKind.ANSWER, value="yes")
    assert score_facts([(frozenset({yes}), frozenset())]).f1 == 0.0


def test_the_bench_prints_the_issues_figures_as_its_last_line(benchmark_path, capsys):
    language.main(["--benchmark", str(benchmark_path), "--split", "val_seen", "--json"])
    figures = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert {"commander", "driver", "baseline", "understand_p95_ms", "model_mb", "split"} <= set(figures)
    assert set(figures["commander"]) == set(figures["baseline"]["commander"]) == {"exact_match", "clause_f1", "turns"}
    assert set(figures["driver"]) == set(figures["baseline"]["driver"]) == {"fact_f1", "turns"}
    assert figures["split"] == "val_seen" and figures["commander"]["turns"] > 150

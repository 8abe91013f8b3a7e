"""The dialog readers: trained on the train split alone, run in numpy exactly as trained in torch,
and reading the train split's own turns as their labellers did."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
import torch

from models.language import FIXED_SOURCE, LABELS_DIR, Config, Seq2Seq, export, hand_examples, train
from models.language_paraphrase import paraphrase_examples
from sim.language.meaning import CLAUSE_FIELDS, Clause, FactForm, Op
from sim.language.reader import (
    BOS,
    DOMAINS,
    EOS,
    HEADS,
    MAX_OUTPUT,
    Reader,
    Role,
    complete,
    decode_meaning,
    normalize,
    output_vocabulary,
    shipped,
    source_tokens,
)
from sim.tasks.benchmark import Benchmark


def _torch_greedy(model: Seq2Seq, reader: Reader, tokens: list[str]) -> list[str]:
    """The torch network's greedy reading under the reader's grammar (teacher forcing what it wrote)."""
    src = torch.tensor([[reader.source.index(t) for t in tokens]])
    written = [reader.target.index(BOS)]
    out: list[str] = []
    pending: list[str] = []
    with torch.no_grad():
        for _ in range(MAX_OUTPUT):
            logits = model(src, torch.tensor([len(tokens)]), torch.tensor([written]))[0, -1].double().numpy()
            mask = reader._masks[pending[0] if pending else "start"]  # noqa: SLF001 - the grammar under test
            token = reader.target[int(np.argmax(logits + mask))]
            if pending:
                pending.pop(0)
            elif token == EOS:
                break
            else:
                pending = [f"{token}.{field}" for field in DOMAINS[token]]
            out.append(token)
            written.append(reader.target.index(token))
    return complete(out, reader.role)


def test_numpy_reads_as_the_torch_network_it_was_exported_from(tmp_path):
    torch.manual_seed(3)
    sentences = ["turn left at the red wall", "go forward 3 steps then turn right", "what do you see?"]
    words = {t for s in sentences for t in source_tokens(s, None)[0]}
    source = FIXED_SOURCE + sorted(words - set(FIXED_SOURCE))  # as training builds it
    target = output_vocabulary(Role.COMMANDER)
    model = Seq2Seq(len(source), len(target), Config(embed=8, hidden=8, decoder=12)).eval()
    export(model, Role.COMMANDER, source, target, tmp_path / "commander.npz")
    reader = Reader(tmp_path / "commander.npz")
    for sentence in sentences:
        tokens, numbers = source_tokens(sentence, None)
        written = _torch_greedy(model, reader, tokens)
        assert reader.decode(tokens)[0] == written
        assert reader.read(sentence).meaning == decode_meaning(Role.COMMANDER, written, numbers)


def test_the_shipped_readers_read_the_train_splits_turns_as_labelled(benchmark_path):
    bench = Benchmark(benchmark_path)
    for role, floor in ((Role.COMMANDER, 0.8), (Role.DRIVER, 0.8)):
        examples = hand_examples(bench, role)[:200]
        reader = shipped(role)
        exact = 0
        for example in examples:
            exact += reader.decode(list(example.source))[0] == list(example.target)
        assert exact / len(examples) >= floor, (role, exact)


def test_a_reader_writes_only_well_formed_meanings():
    reader = shipped(Role.COMMANDER)
    for text in ("", "???", "flip around and go 35 cm", "blah blah blah", "left 3"):
        for clause in reader.read(text).meaning:
            assert isinstance(clause, Clause) and clause.op in HEADS[Role.COMMANDER]
            Clause.from_json(clause.to_json())
    for text in ("yes", "i see red on my left and the jar ahead", "where?"):
        for fact in shipped(Role.DRIVER).read(text, ("c", "is there a red wall on your left?")).meaning:
            FactForm.from_json(fact.to_json())


def test_counts_it_never_saw_are_read_from_the_turn():
    program = shipped(Role.COMMANDER).read("go forward 17 steps").meaning
    assert Clause.of(Op.FORWARD, steps=17, until=None) in program


@pytest.mark.slow
def test_training_reads_no_turn_of_val_seen_or_test(benchmark_path, tmp_path):
    # A benchmark with the train split alone: training must not need, or open, the others.
    only_train = tmp_path / "bench"
    (only_train / "NDH-data").mkdir(parents=True)
    shutil.copy(benchmark_path / "NDH-data" / "train.json", only_train / "NDH-data" / "train.json")
    (only_train / "mazedata").symlink_to(benchmark_path / "mazedata")
    report = train(Benchmark(only_train), Config(epochs=1, selfplay_trials=2), tmp_path / "out")
    assert report["readers"]["commander"]["hand_labelled"] == sum(1 for _ in (LABELS_DIR / "commander.jsonl").open())
    assert Reader(tmp_path / "out" / "driver.npz").role == Role.DRIVER
    assert json.loads((tmp_path / "out" / "training.json").read_text())["readers"]["driver"]["rules_labelled"] > 0


def test_paraphrased_turns_name_every_count_their_programs_hold():
    # The reader copies a count from the turn: a paraphrase whose words lost its count (a slip on a
    # digit, centimetres that round to another step count) would teach it to invent one.
    for text, program in paraphrase_examples(seed=0, n=600):
        _, numbers = normalize(text)
        for clause in program:
            steps = dict(zip(CLAUSE_FIELDS[clause.op], clause.args, strict=True)).get("steps")
            assert steps is None or steps in numbers, (text, program)


def test_hand_labels_hold_train_turns_only():
    for role in Role:
        for line in (LABELS_DIR / f"{role.value}.jsonl").open():
            assert json.loads(line)["id"].startswith("train/")

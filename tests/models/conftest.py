"""A few real benchmark instances and their mazes compiled into a small World."""

from __future__ import annotations

import pytest

from models.data import EpisodeSet, World
from models.tokenizer import Tokenizer
from sim.tasks.benchmark import Benchmark


@pytest.fixture(scope="session")
def bench(benchmark_path) -> Benchmark:
    return Benchmark(benchmark_path)


@pytest.fixture(scope="session")
def few(bench) -> dict:
    train = bench.split("train")[:8]
    val = bench.split("val_seen")[:4]
    world = World.build(bench, sorted({i.run for i in train + val}))
    tokenizer = Tokenizer.from_dialogs((i.dialog, i.target) for i in train)
    return {
        "train": train,
        "val": val,
        "world": world,
        "tokenizer": tokenizer,
        "train_set": EpisodeSet.build(bench, world, "train", tokenizer, instances=train),
        "val_set": EpisodeSet.build(bench, world, "val_seen", tokenizer, instances=val),
    }

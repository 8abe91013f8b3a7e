"""`experiment ndh --executor ray`: each training run is a Ray task, on a local Ray instance
started here; a run cut short (as by a lost worker) resumes, a finished one is skipped."""

from __future__ import annotations

import json
import os
from dataclasses import asdict

import pytest

from models.experiment import _run_jobs
from models.train import TrainConfig, build_world, train
from sim.tasks.benchmark import Benchmark

ray = pytest.importorskip("ray", reason="the cluster extra is not installed: pip install .[cluster]")


def tiny(seed: int, iters: int) -> dict:
    # A reduced protocol: a few batches of 4 short episodes, no validation.
    return asdict(
        TrainConfig(feedback="student", seed=seed, iters=iters, batch=4, eval_every=2, max_actions=10, eval_split=None)
    )


@pytest.fixture
def local_ray():
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


@pytest.mark.slow
def test_ray_tasks_resume_a_cut_short_run_and_skip_a_finished_one(benchmark_path, tmp_path, local_ray):
    bench = Benchmark(benchmark_path, cache_dir=os.environ["ROBOTSLANG_CACHE_DIR"])  # the tasks load the world
    world = build_world(bench, bench.cache_dir)  # compiled once, into the cache the tasks read
    cut, done = tmp_path / "seed0", tmp_path / "seed1"
    train(bench, TrainConfig(**tiny(0, 2)), cut, world=world, progress=False)  # its worker was lost after 2
    train(bench, TrainConfig(**tiny(1, 4)), done, world=world, progress=False)
    finished = (done / "last.pt").stat().st_mtime_ns

    results = _run_jobs([(tiny(0, 4), cut), (tiny(1, 4), done)], bench, 1, "ray", executor="ray")

    assert [e["iteration"] for e in results[0]["history"]] == [2, 4]  # went on from its checkpoint
    assert [e["iteration"] for e in results[1]["history"]] == [2, 4]
    assert (done / "last.pt").stat().st_mtime_ns == finished  # nothing left to train: untouched
    assert json.loads((cut / "history.json").read_text()) == results[0]["history"]

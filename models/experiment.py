"""`robotslang experiment ndh`: the paper's whole protocol, end to end.

For each model variant, feedback (teacher, student), ablation (none, vision, language) and
seed: train on `train`, validate on `val_seen` and keep the iteration with the best TD; then
retrain on train + val_seen to that iteration for `test`. Every trained Driver is evaluated
(val_seen from the validation run, test from the retrained one), next to the Random and
Immediate Stop baselines, into one per-instance CSV per split; the significance tests and the
report are built from those CSVs. Re-running on the same OUT resumes: finished trainings are
kept and only what is missing is done.

The trainings run on an executor: `local`, a process pool on this machine, or `ray`, one Ray
task per run (`pip install .[cluster]`), on a Ray cluster or a local instance. Each task trains
into its own run folder, which must be on storage every node sees; a task whose worker is lost
is retried by Ray and resumes from that run's last checkpoint, and runs already written are
skipped (their training has nothing left to do).
"""

from __future__ import annotations

import json
import math
import os
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import asdict
from multiprocessing import get_context
from pathlib import Path

from tqdm import tqdm

from models.train import MODELS, TrainConfig, build_world, train
from sim.tasks.benchmark import Benchmark

EXECUTORS = ("local", "ray")
RAY_TASK_RETRIES = 3  # a lost worker's run is started again this many times
FEEDBACKS = ("teacher", "student")
ABLATIONS = ("none", "vision", "language")
BASELINE_AGENTS = ("random", "stop")
PROBE_ITERS = 3
EVALS_PER_RUN = 8
EVAL_COST_ITERS = 0.5  # a validation pass costs about half a training iteration
RETRAIN_SHARE = 0.75  # test retraining runs to the best iteration, on average this share of all


def config_name(model: str, feedback: str, blind: str) -> str:
    return f"{model}/{feedback}/{blind}"


def run_dir(out: Path, model: str, feedback: str, blind: str, seed: int) -> Path:
    return out / "runs" / model / f"{feedback}-{blind}" / f"seed{seed}"


def experiment_grid(
    models: list[str], feedbacks: list[str], ablations: list[str], seeds: list[int]
) -> list[tuple[str, str, str, int]]:
    """Every (model, feedback, ablation, seed) run of the protocol, in its canonical order; a
    subset of the feedbacks or ablations runs only those configurations."""
    for name, chosen, known in (
        ("model", models, tuple(MODELS)),
        ("feedback", feedbacks, FEEDBACKS),
        ("ablation", ablations, ABLATIONS),
    ):
        unknown = [c for c in chosen if c not in known]
        if not chosen or unknown:
            raise ValueError(f"unknown {name}(s) {', '.join(unknown) or '(none given)'}; expected {', '.join(known)}")
    return [
        (m, f, b, s)
        for m in models
        for f in FEEDBACKS
        if f in feedbacks
        for b in ABLATIONS
        if b in ablations
        for s in seeds
    ]


def measure_iteration_seconds(
    bench: Benchmark, out: Path, model: str, feedbacks: tuple[str, ...] | list[str] = FEEDBACKS
) -> dict[str, float]:
    """Seconds per training iteration for each feedback, from a short run of each."""
    world = build_world(bench, bench.cache_dir)
    costs = {}
    for feedback in feedbacks:
        probe = out / "probe" / f"{model}-{feedback}"
        cfg = TrainConfig(feedback=feedback, model=model, iters=PROBE_ITERS, eval_every=PROBE_ITERS, eval_split=None)
        for f in ("last.pt", "best.pt"):
            (probe / f).unlink(missing_ok=True)
        result = train(bench, cfg, probe, world=world, progress=False, threads=1)
        costs[feedback] = result["seconds"] / PROBE_ITERS  # the training loop only, not its setup
    return costs


def choose_iters(
    costs: dict[str, float],
    n_models: int,
    n_seeds: int,
    budget_s: float,
    workers: int,
    n_ablations: int = len(ABLATIONS),
) -> int:
    """Training iterations per run that fit the budget: each run costs its iterations, the
    retraining to its best iteration (RETRAIN_SHARE of them on average) and its validations;
    `costs` holds the feedbacks run."""
    per_iter = sum(costs.values()) * n_ablations * n_models * n_seeds  # one iteration of every run
    validations = EVALS_PER_RUN * EVAL_COST_ITERS
    return max(10, int((budget_s * workers / per_iter - validations) / (1 + RETRAIN_SHARE)))


def _train_job(root: str, cache_dir: str | None, cfg: dict, out: str) -> dict:
    bench = Benchmark(root, cache_dir=cache_dir)
    return train(bench, TrainConfig(**cfg), out, progress=False, threads=1)


def _run_jobs(
    jobs: list[tuple[dict, Path]],
    bench: Benchmark,
    workers: int,
    desc: str,
    executor: str = "local",
    address: str | None = None,
) -> list[dict]:
    bar = tqdm(total=len(jobs), desc=desc, unit="run")
    root, cache = str(bench.root), (str(bench.cache_dir) if bench.cache_dir else None)
    if executor == "ray":
        return _run_ray_jobs(jobs, root, cache, address, bar)
    if workers <= 1:
        results = []
        for cfg, out in jobs:
            results.append(_train_job(root, cache, cfg, str(out)))
            bar.update()
        return results
    with ProcessPoolExecutor(workers, mp_context=get_context("spawn")) as pool:
        futures = [pool.submit(_train_job, root, cache, cfg, str(out)) for cfg, out in jobs]
        for f in futures:
            f.add_done_callback(lambda _: bar.update())
        return [f.result() for f in futures]


def _run_ray_jobs(jobs: list[tuple[dict, Path]], root: str, cache: str | None, address: str | None, bar) -> list[dict]:
    """Every run as a Ray task of one CPU, on the cluster at `address` (None: a Ray instance
    already started in this process, else a new local one); results in the order of `jobs`."""
    import ray

    if not ray.is_initialized():
        ray.init(address=address, log_to_driver=False)
    task = ray.remote(num_cpus=1, max_retries=RAY_TASK_RETRIES, retry_exceptions=False)(_train_job)
    refs = [task.remote(root, cache, cfg, str(Path(out).resolve())) for cfg, out in jobs]
    pending = list(refs)
    while pending:
        done, pending = ray.wait(pending, num_returns=1)
        bar.update(len(done))
    return ray.get(refs)


def run_experiment(
    bench: Benchmark,
    out: str | Path,
    models: list[str],
    seeds: list[int],
    iters: int | None = None,
    budget_minutes: float = 110.0,
    workers: int = 1,
    eval_every: int | None = None,
    executor: str = "local",
    address: str | None = None,
    feedbacks: list[str] | None = None,
    ablations: list[str] | None = None,
) -> dict:
    from models.evaluate import evaluate_checkpoint
    from models.report import write_report
    from sim.core.metrics import summarize, write_csv
    from sim.tasks.evaluation import evaluate_baselines

    if executor not in EXECUTORS:
        raise ValueError(f"unknown executor {executor!r}; expected one of {', '.join(EXECUTORS)}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    feedbacks = list(feedbacks or FEEDBACKS)
    ablations = list(ablations or ABLATIONS)
    grid = experiment_grid(models, feedbacks, ablations, seeds)
    began = time.perf_counter()
    timing: dict[str, float] = {}
    world = build_world(bench, bench.cache_dir)
    timing["world_s"] = time.perf_counter() - began

    meta_path = out / "experiment.json"
    meta = json.loads(meta_path.read_text()) if meta_path.exists() else {}
    if iters is None and "iters" in meta:
        iters = meta["iters"]  # a resumed experiment keeps its sizing
    costs = meta.get("iteration_seconds")
    if iters is None:
        # An untrained agent that may stop anywhere (a critic's) ends its probe episodes early,
        # so no variant is taken to be cheaper than the baseline, whose student runs to the cap.
        costs = {m: measure_iteration_seconds(bench, out, m, feedbacks) for m in dict.fromkeys(["baseline", *models])}
        mean_cost = {f: sum(max(costs[m][f], costs["baseline"][f]) for m in models) / len(models) for f in feedbacks}
        budget_s = budget_minutes * 60 - timing["world_s"] - 300
        iters = choose_iters(mean_cost, len(models), len(seeds), budget_s, workers, len(ablations))
    eval_every = eval_every or max(1, math.ceil(iters / EVALS_PER_RUN))
    meta = {
        "models": models,
        "feedbacks": feedbacks,
        "ablations": ablations,
        "seeds": seeds,
        "iters": iters,
        "eval_every": eval_every,
        "workers": workers,
        "executor": executor,
        "budget_minutes": budget_minutes,
        "iteration_seconds": costs,
        "cpus": os.cpu_count(),
    }
    meta_path.write_text(json.dumps(meta, indent=2))

    t0 = time.perf_counter()
    val_jobs = [
        (
            asdict(TrainConfig(feedback=f, blind=b, seed=s, model=m, iters=iters, eval_every=eval_every)),
            run_dir(out, m, f, b, s) / "val",
        )
        for m, f, b, s in grid
    ]
    val_runs = _run_jobs(val_jobs, bench, workers, "train (val_seen)", executor, address)
    timing["train_val_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    test_jobs = []
    for (m, f, b, s), run in zip(grid, val_runs):
        best = run["best"]["iteration"] or iters
        test_jobs.append(
            (
                asdict(
                    TrainConfig(
                        feedback=f,
                        blind=b,
                        seed=s,
                        model=m,
                        iters=best,
                        eval_every=best,
                        train_splits=["train", "val_seen"],
                        eval_split=None,
                    )
                ),
                run_dir(out, m, f, b, s) / "test",
            )
        )
    _run_jobs(test_jobs, bench, workers, "retrain (train+val_seen)", executor, address)
    timing["train_test_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    summaries = {}
    for split, ckpt_name in (("val_seen", "val/best.pt"), ("test", "test/last.pt")):
        results = evaluate_baselines(bench, split, BASELINE_AGENTS, seeds=seeds, progress=False)
        for m, f, b, s in tqdm(grid, desc=f"evaluate {split}", unit="run"):
            ckpt = run_dir(out, m, f, b, s) / ckpt_name
            results += evaluate_checkpoint(bench, world, ckpt, split, name=config_name(m, f, b))
        write_csv(out / "results" / f"{split}.csv", results)
        summaries[split] = summarize(split, results)
        (out / "results" / f"summary_{split}.json").write_text(json.dumps(summaries[split], indent=2))
    timing["evaluate_s"] = time.perf_counter() - t0
    timing["total_s"] = time.perf_counter() - began
    meta["timing"] = timing
    meta["best_iterations"] = {f"{config_name(m, f, b)}/seed{s}": r["best"] for (m, f, b, s), r in zip(grid, val_runs)}
    meta_path.write_text(json.dumps(meta, indent=2))
    write_report(out)
    return meta

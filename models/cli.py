"""`robotslang train ndh`, `eval ndh`, `report ndh`, `experiment ndh`.

torch is imported inside the commands, so that `robotslang --help` stays fast.
"""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path

import typer

from sim.cli.eval import BENCHMARK_OPTION, open_benchmark, parse_list, parse_seeds
from sim.tasks.benchmark import Split


class Feedback(StrEnum):
    teacher = "teacher"
    student = "student"


class Blind(StrEnum):
    none = "none"
    vision = "vision"
    language = "language"


class Model(StrEnum):
    baseline = "baseline"
    improved = "improved"
    attention = "attention"


class Executor(StrEnum):
    local = "local"
    ray = "ray"


class TrainOn(StrEnum):
    train = "train"
    train_val = "train+val_seen"


def train_ndh(
    benchmark: Path = BENCHMARK_OPTION,
    feedback: Feedback = typer.Option(Feedback.student, help="teacher (lr 1e-4) or student (lr 1e-3) forcing."),
    blind: Blind = typer.Option(
        Blind.none, help="Ablation: none, vision (observations zeroed) or language (dialog emptied)."
    ),
    seed: int = typer.Option(0, help="Random seed."),
    iters: int = typer.Option(2000, help="Training iterations (batches of 100)."),
    out: Path = typer.Option(..., help="Run folder: best.pt, last.pt, history.json; resumes from last.pt."),
    model: Model = typer.Option(
        Model.baseline,
        help="baseline: the paper's model; improved: target flags, "
        "actor-critic on the distance covered, averaged weights; attention: attention "
        "over the dialog, a progress monitor and target flags.",
    ),
    eval_every: int = typer.Option(200, help="Validate on val_seen every this many iterations."),
    train_on: TrainOn = typer.Option(
        TrainOn.train, help="train, or train+val_seen (the test-time retraining; no validation)."
    ),
    glove: Path | None = typer.Option(None, help="GloVe text file to initialise the word embeddings."),
    lr: float | None = typer.Option(None, help="Learning rate; default the paper's for the feedback."),
) -> None:
    """Train the NDH seq2seq Driver (progress bar with live loss and validation TD)."""
    from models.train import TrainConfig, train

    if glove is not None and not glove.is_file():
        raise typer.BadParameter(f"{glove}: no such file", param_hint="--glove")
    bench = open_benchmark(benchmark)
    splits = train_on.value.split("+")
    try:
        cfg = TrainConfig(
            feedback=feedback.value,
            blind=blind.value,
            seed=seed,
            iters=iters,
            model=model.value,
            eval_every=eval_every,
            train_splits=splits,
            eval_split=None if "val_seen" in splits else "val_seen",
            glove=str(glove) if glove else None,
            lr=lr,
        )
        result = train(bench, cfg, out)
    except ValueError as e:
        raise typer.BadParameter(str(e)) from None
    best = result["best"]
    if best["iteration"] is not None:
        typer.echo(f"best val_seen TD {best['val_td']:.3f} at iteration {best['iteration']} -> {out / 'best.pt'}")
    typer.echo(f"last checkpoint -> {out / 'last.pt'} ({result['seconds']:.0f} s)")


def eval_ndh(
    benchmark: Path = BENCHMARK_OPTION,
    checkpoint: Path | None = typer.Option(
        None,
        help="A checkpoint written by `train ndh`; default the Driver shipped in the package (docs/model_card_ndh.md).",
    ),
    split: Split = typer.Option(Split.VAL_SEEN, help="NDH split."),
    as_json: bool = typer.Option(False, "--json", help="Print JSON (the shape of `eval baselines`)."),
    per_instance: Path | None = typer.Option(None, help="Write a CSV row per instance."),
    name: str | None = typer.Option(None, help="Agent name in the output; default from the checkpoint."),
) -> None:
    """Score a trained Driver: TD, OTD, SR, SPL (mean ± std)."""
    from models.evaluate import evaluate_checkpoint
    from models.shipped import default_checkpoint
    from sim.cli.eval import print_results

    checkpoint = checkpoint or default_checkpoint()
    if checkpoint is None:
        raise typer.BadParameter("this install ships no Driver; give a checkpoint", param_hint="--checkpoint")
    bench = open_benchmark(benchmark)
    try:
        results = evaluate_checkpoint(bench, None, checkpoint, split.value, name=name)
    except (FileNotFoundError, ValueError) as e:
        raise typer.BadParameter(str(e), param_hint="--checkpoint") from None
    print_results(split.value, results, as_json, per_instance)


def report_ndh(directory: Path = typer.Argument(..., help="An experiment folder (`experiment ndh --out`).")) -> None:
    """Write the result tables (Markdown) and TD/learning-curve plots (PNG) of an experiment."""
    from models.report import write_report

    try:
        path = write_report(directory)
    except FileNotFoundError as e:
        raise typer.BadParameter(str(e), param_hint="DIR") from None
    typer.echo(f"report -> {path}")


def experiment_ndh(
    benchmark: Path = BENCHMARK_OPTION,
    out: Path = typer.Option(Path("runs/ndh-experiment"), help="Experiment folder; re-running resumes."),
    models: str = typer.Option("baseline,improved", help="Model variants, comma-separated."),
    seeds: str = typer.Option("0,1,2", help="Seeds, comma-separated."),
    feedbacks: str = typer.Option("teacher,student", help="Feedbacks run, comma-separated (a subset of the protocol)."),
    ablations: str = typer.Option(
        "none,vision,language", help="Ablations run, comma-separated (none: the full model; a subset of the protocol)."
    ),
    iters: int | None = typer.Option(None, help="Iterations per run; default: measured to fit the budget."),
    budget_minutes: float = typer.Option(110.0, help="Wall-time budget used to size --iters."),
    eval_every: int | None = typer.Option(
        None, help="Validate on val_seen every this many iterations; default: 8 validations per run."
    ),
    workers: int = typer.Option(2, help="Trainings run in parallel (one CPU thread each), with --executor local."),
    executor: Executor = typer.Option(
        Executor.local,
        help="local: a process pool on this machine; ray: one Ray "
        "task per run (pip install .[cluster]; run folders on shared storage).",
    ),
    address: str | None = typer.Option(
        None,
        help="With --executor ray: the cluster's address (e.g. "
        "ray://HEAD:10001 or auto); default a new local Ray instance.",
    ),
) -> None:
    """The whole protocol: 6 configurations x seeds (or the subset --feedbacks x --ablations),
    validation, retraining for test, tests, report."""
    from models.experiment import experiment_grid, run_experiment

    model_list, feedback_list, ablation_list = (
        parse_list(text, kind) for text, kind in ((models, "model"), (feedbacks, "feedback"), (ablations, "ablation"))
    )
    seed_list = parse_seeds(seeds)
    try:
        experiment_grid(model_list, feedback_list, ablation_list, seed_list)
    except ValueError as e:
        raise typer.BadParameter(str(e), param_hint="--models/--feedbacks/--ablations") from None
    if address is not None and executor is not Executor.ray:
        raise typer.BadParameter("--address is for --executor ray", param_hint="--address")
    if executor is Executor.ray:
        try:
            import ray  # noqa: F401
        except ImportError:
            raise typer.BadParameter("Ray is not installed: pip install .[cluster]", param_hint="--executor") from None
    meta = run_experiment(
        open_benchmark(benchmark),
        out,
        model_list,
        seed_list,
        iters=iters,
        budget_minutes=budget_minutes,
        workers=workers,
        eval_every=eval_every,
        executor=executor.value,
        address=address,
        feedbacks=feedback_list,
        ablations=ablation_list,
    )
    typer.echo(
        f"{meta['iters']} iterations per run; {meta['timing']['total_s'] / 60:.1f} min; report -> {out / 'report.md'}"
    )


def train_language(
    benchmark: Path = BENCHMARK_OPTION,
    seed: int = typer.Option(0, help="Random seed."),
    out: Path = typer.Option(..., help="Folder for commander.npz, driver.npz and training.json."),
    epochs: int = typer.Option(40, help="Passes over the examples."),
) -> None:
    """Train the dialog readers on the train split (docs/model_card_language.md); about 10 minutes on 2 cores."""
    from models.language import Config, train

    report = train(open_benchmark(benchmark), Config(seed=seed, epochs=epochs), out)
    for role, figures in report["readers"].items():
        typer.echo(
            f"{role}: {figures['hand_labelled']} hand-labelled + {figures['rules_labelled']} rules-labelled turns, "
            f"final loss {figures['loss'][-1]:.4f}"
        )
    typer.echo(f"{report['seconds'] / 60:.1f} min; readers -> {out}")


def register(root: typer.Typer, eval_app: typer.Typer) -> None:
    """Mount this package's commands on the root CLI."""
    train_app = typer.Typer(help="Train learned Drivers and the dialog readers.", no_args_is_help=True)
    train_app.command("ndh")(train_ndh)
    train_app.command("language")(train_language)
    root.add_typer(train_app, name="train")
    eval_app.command("ndh")(eval_ndh)
    report_app = typer.Typer(help="Reports of experiments.", no_args_is_help=True)
    report_app.command("ndh")(report_ndh)
    root.add_typer(report_app, name="report")
    experiment_app = typer.Typer(help="End-to-end experiments.", no_args_is_help=True)
    experiment_app.command("ndh")(experiment_ndh)
    root.add_typer(experiment_app, name="experiment")
    from models import ldh_cli

    eval_app.command("ldh")(ldh_cli.eval_ldh)
    train_app.command("ldh")(ldh_cli.train_ldh)
    experiment_app.command("ldh")(ldh_cli.experiment_ldh)

"""`robotslang eval ldh`, `train ldh`, `experiment ldh`: Localization from Dialog History.

torch is imported only where a checkpoint is trained or read.
"""

from __future__ import annotations

import json
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING

import typer

from sim.cli.eval import BENCHMARK_OPTION, open_benchmark, parse_list, parse_seeds
from sim.tasks.benchmark import Split

if TYPE_CHECKING:
    from sim.tasks.ldh_eval import LDHSummary

LEARNED = "learned"


class VariantOption(StrEnum):
    prefix = "prefix"
    full = "full"


def print_table(summary: LDHSummary) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"LDH {summary['split']} {summary['variant']} (n={summary['n']})")
    for col in ("agent", "TD (m)", "median TD", "Euclid (m)", "acc@0.25", "acc@0.5", "acc@1.0"):
        table.add_column(col, justify="left" if col == "agent" else "right")
    for name, s in summary["agents"].items():
        table.add_row(
            name,
            f"{s['td_mean']:.3f} ± {s['td_std']:.3f}",
            f"{s['td_median']:.3f}",
            f"{s['euclid_mean']:.3f}",
            f"{s['acc_0.25']:.3f}",
            f"{s['acc_0.5']:.3f}",
            f"{s['acc_1.0']:.3f}",
        )
    Console().print(table)


def eval_ldh(
    benchmark: Path = BENCHMARK_OPTION,
    split: Split = typer.Option(Split.VAL_SEEN, help="Split (by maze, as the benchmark's)."),
    agent: str = typer.Option(
        "random,center,colours",
        help=f"Localizers, comma-separated: random, center, colours, dialog, {LEARNED} (needs --checkpoint).",
    ),
    checkpoint: Path | None = typer.Option(None, help="A checkpoint written by `train ldh`."),
    variant: VariantOption = typer.Option(
        VariantOption.prefix,
        help="prefix: the dialog up to the end of "
        "localization (rule prefix-v1); full: the whole first sub-dialog. "
        "A folder with LDH-data/ (a platform export) is read as is.",
    ),
    as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table."),
    per_instance: Path | None = typer.Option(None, help="Write a CSV row per instance and agent."),
    curve: Path | None = typer.Option(None, help="Write the per-turn curve (TD after each Driver turn) as JSON."),
    plot: Path | None = typer.Option(None, help="Draw the per-turn curve as a PNG (matplotlib)."),
    versus: str | None = typer.Option(
        None, help="Paired t-tests on per-instance TD of every other agent against this one (BY-corrected)."
    ),
) -> None:
    """Score localizers on LDH: TD and Euclidean error (m), accuracy within 0.25/0.5/1.0 m."""
    from rich.progress import track

    from sim.tasks.benchmark import BenchmarkError
    from sim.tasks.ldh import Variant, load_split
    from sim.tasks.ldh_dialog import DIALOG, DialogLocalizer, per_turn, plot_curve
    from sim.tasks.ldh_eval import BASELINES, Localizer, MazeContexts, evaluate, summarize, write_csv

    names = parse_list(agent, "agent", [*BASELINES, DIALOG, LEARNED])
    if versus is not None and versus not in names:
        raise typer.BadParameter(f"{versus!r} is not among the agents evaluated", param_hint="--versus")
    agents: dict[str, Localizer] = {name: BASELINES[name] for name in names if name in BASELINES}
    if LEARNED in names:
        if checkpoint is None:
            raise typer.BadParameter(f"agent {LEARNED} needs --checkpoint", param_hint="--agent")
        from models.ldh import load_localizer

        try:
            agents[LEARNED] = load_localizer(checkpoint)
        except (FileNotFoundError, ValueError) as e:
            raise typer.BadParameter(str(e), param_hint="--checkpoint") from None
    bench = open_benchmark(benchmark)
    if DIALOG in names:
        from sim.language.reader import Role, shipped

        agents[DIALOG] = DialogLocalizer(bench, reader=shipped(Role.DRIVER))
    agents = {name: agents[name] for name in names}  # in the order asked for
    try:
        instances = load_split(bench, split.value, Variant(variant.value))
    except BenchmarkError as e:
        raise typer.BadParameter(str(e), param_hint="--benchmark") from None
    if not instances:
        raise typer.BadParameter(f"split {split.value} has no LDH instances", param_hint="--split")
    shown = instances[0].variant.value
    contexts = MazeContexts(bench)
    results = evaluate(
        bench,
        split.value,
        instances,
        agents,
        contexts=contexts,
        progress=lambda it: track(it, description="localizing", disable=as_json),
    )
    summary = summarize(split.value, shown, len(instances), results)
    if versus is not None and len(instances) > 1:
        from models.stats import paired_tests

        others = [(name, versus) for name in names if name != versus]
        summary["tests"] = [c.to_dict() for c in paired_tests(results, others)]
    if per_instance is not None:
        write_csv(per_instance, results)
    if curve is not None or plot is not None:
        turns = per_turn(bench, instances, agents, contexts)
        if curve is not None:
            curve.parent.mkdir(parents=True, exist_ok=True)
            curve.write_text(json.dumps({"split": split.value, "variant": shown, **turns}, indent=2))
        if plot is not None:
            plot_curve(turns, plot, f"LDH {split.value} ({shown}): TD after each Driver turn")
    if as_json:
        typer.echo(json.dumps(summary, indent=2))
    else:
        print_table(summary)
        for c in summary.get("tests", []):
            typer.echo(
                f"{c['a']} vs {c['b']}: TD {c['mean_a']:.3f} vs {c['mean_b']:.3f}, t {c['t']:.2f}, p {c['p']:.4f}"
            )


def train_ldh(
    benchmark: Path = BENCHMARK_OPTION,
    seed: int = typer.Option(0, help="Random seed."),
    out: Path = typer.Option(..., help="Run folder: best.pt (best val_seen TD), history.json."),
    epochs: int = typer.Option(30, help="Epochs over the training dialogs (plus fresh synthetic ones)."),
    synthetic: int = typer.Option(0, help="Synthetic Driver descriptions mixed in per epoch (0: real dialogs only)."),
    dropout: float = typer.Option(0.5, help="Dropout on the dialog's mention counts."),
    prior: bool = typer.Option(True, help="Start from the colour baseline's scores (a learned weight)."),
    variant: VariantOption = typer.Option(VariantOption.prefix, help="LDH input: prefix or full."),
) -> None:
    """Train the learned LDH localizer (progress bar with loss and val_seen TD)."""
    from models.ldh import LDHConfig, train

    try:
        result = train(
            open_benchmark(benchmark),
            LDHConfig(
                seed=seed, epochs=epochs, synthetic=synthetic, dropout=dropout, prior=prior, variant=variant.value
            ),
            out,
        )
    except ValueError as e:
        raise typer.BadParameter(str(e)) from None
    best = result["best"]
    typer.echo(
        f"best val_seen TD {best['val_td']:.3f} at epoch {best['epoch']} -> {out / 'best.pt'} "
        f"({result['seconds']:.0f} s)"
    )


def experiment_ldh(
    benchmark: Path = BENCHMARK_OPTION,
    out: Path = typer.Option(Path("runs/ldh-experiment"), help="Experiment folder (runs, results.json)."),
    seeds: str = typer.Option("0,1,2", help="Seeds, comma-separated."),
    doc: Path = typer.Option(Path("docs/ldh.md"), help="Markdown page whose results block is rewritten."),
) -> None:
    """Baselines, the learned localizer and its ablations (3 seeds) on val_seen, then test once."""
    from models.ldh_experiment import run_experiment

    meta = run_experiment(open_benchmark(benchmark), out, parse_seeds(seeds), doc)
    learned = meta["test"]["agents"]["learned"]
    typer.echo(
        f"test TD learned {learned['td_mean']:.3f} m; {meta['timing']['total_s'] / 60:.1f} min; "
        f"results -> {out / 'results.json'}, {doc}"
    )

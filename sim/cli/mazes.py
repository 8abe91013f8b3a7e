"""`robotslang mazes generate | list | layouts | folds | show`: the maze library from the command line."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import cv2
import typer
from rich.progress import track

from sim.core.maze import MazeError
from sim.tasks.benchmark import Benchmark, BenchmarkError, Split
from sim.tasks.generator import generate_maze
from sim.tasks.layouts import fold_counts, layout_of
from sim.tasks.library import MANIFEST, MazeLibrary, UnknownMazeError

app = typer.Typer(help="Generate, list and draw mazes.", no_args_is_help=True)

BENCHMARK_OPTION = typer.Option(
    None,
    "--benchmark",
    envvar="ROBOTSLANG_BENCHMARK",
    help="A clone of the RobotSlang benchmark, to include its mazes.",
)


def generate_set(out: Path, count: int, seed: int, prefix: str = "gen", progress: bool = True) -> dict[str, Any]:
    """Write `count` mazes (`PREFIX-000` ... from seeds seed, seed+1, ...) and their manifest."""
    out.mkdir(parents=True, exist_ok=True)
    entries = []
    for i in track(range(count), description="Generating mazes", disable=not progress):
        name = f"{prefix}-{i:03d}"
        maze = generate_maze(seed + i, name=name)
        maze.save(out / name)
        entries.append(
            {
                "name": name,
                "seed": seed + i,
                "objects": {k: [round(x, 4), round(y, 4)] for k, (x, y) in maze.objects.items()},
            }
        )
    manifest = {"generator": "sim.tasks.generator.generate_maze", "seed": seed, "count": count, "mazes": entries}
    (out / MANIFEST).write_text(json.dumps(manifest, indent=2) + "\n")
    return manifest


@app.command("generate")
def generate(
    count: int = typer.Option(12, "--count", min=1, help="How many mazes."),
    seed: int = typer.Option(0, "--seed", min=0, help="Seed of the first maze; maze i uses seed + i."),
    out: Path = typer.Option(..., "--out", help="Folder to write NAME/maze/*.png and manifest.json into."),
    prefix: str = typer.Option("gen", "--prefix", help="Maze names are PREFIX-000, PREFIX-001, ..."),
) -> None:
    """Generate seeded mazes in the benchmark's layout."""
    try:
        generate_set(out, count, seed, prefix)
    except MazeError as e:
        typer.echo(f"error: {e}", err=True)
        raise typer.Exit(1) from None
    typer.echo(f"wrote {count} mazes and {MANIFEST} to {out}")


def _library(benchmark: Path | None, extra: list[Path]) -> MazeLibrary:
    try:
        return MazeLibrary(benchmark, extra_dirs=extra)
    except FileNotFoundError as e:
        raise typer.BadParameter(str(e), param_hint="--benchmark") from None


@app.command("list")
def list_mazes(
    benchmark: Path | None = BENCHMARK_OPTION,
    extra: list[Path] = typer.Option([], "--dir", help="A folder of mazes to include (repeatable)."),
    with_layouts: bool = typer.Option(False, "--layouts", help="Add each maze's physical layout (a third column)."),
) -> None:
    """Every maze name with where it comes from (and its layout)."""
    library = _library(benchmark, extra)
    of = layout_of(library.layouts()) if with_layouts else {}
    for name in library.names():
        typer.echo(f"{name}\t{library.source(name)}" + (f"\t{of[name]}" if with_layouts else ""))


@app.command("layouts")
def layouts(
    benchmark: Path | None = BENCHMARK_OPTION,
    extra: list[Path] = typer.Option([], "--dir", help="A folder of mazes to include (repeatable)."),
    as_json: bool = typer.Option(False, "--json", help='Print {"layouts": [{"id", "runs"}]}.'),
) -> None:
    """The mazes grouped by physical layout: runs on the same table under different names."""
    try:
        found = _library(benchmark, extra).layouts()
    except MazeError as e:
        typer.echo(f"error: {e}", err=True)
        raise typer.Exit(1) from None
    if as_json:
        typer.echo(json.dumps({"layouts": [layout.as_json() for layout in found]}))
        return
    for layout in found:
        typer.echo(f"{layout.id}\t{' '.join(layout.runs)}")
    typer.echo(f"{sum(len(layout.runs) for layout in found)} mazes, {len(found)} layouts")


@app.command("folds")
def folds(
    benchmark: Path = typer.Option(..., "--benchmark", envvar="ROBOTSLANG_BENCHMARK", help="A benchmark clone."),
    as_json: bool = typer.Option(False, "--json", help='Print {"folds": [...], "runs", "layouts"}.'),
) -> None:
    """The benchmark's splits counted in instances, runs and layouts, and the layouts two splits share."""
    try:
        bench = Benchmark(benchmark)
        splits = {str(split): [inst.run for inst in bench.split(split)] for split in Split}
    except BenchmarkError as e:
        typer.echo(f"error: {e}", err=True)
        raise typer.Exit(1) from None
    of = layout_of(_library(benchmark, []).layouts())
    runs = {run for split_runs in splits.values() for run in split_runs}
    counts = fold_counts(splits, of)
    total = {"runs": len(runs), "layouts": len({of.get(run, run) for run in runs})}
    if as_json:
        typer.echo(json.dumps({"folds": counts, **total}))
        return
    typer.echo("split\tinstances\truns\tlayouts\tlayouts in another split")
    for c in counts:
        typer.echo(f"{c['split']}\t{c['instances']}\t{c['runs']}\t{c['layouts']}\t{c['shared_layouts']}")
    typer.echo(f"all\t{sum(c['instances'] for c in counts)}\t{total['runs']}\t{total['layouts']}")


@app.command("show")
def show(
    name: str,
    out: Path = typer.Option(..., "--out", help="PNG file to write the map to."),
    benchmark: Path | None = BENCHMARK_OPTION,
    extra: list[Path] = typer.Option([], "--dir", help="A folder of mazes to include (repeatable)."),
    walls_only: bool = typer.Option(False, "--walls-only", help="Draw the walls-only map."),
) -> None:
    """Draw a maze's map, in the benchmark's colours, to a PNG."""
    try:
        maze = _library(benchmark, extra).load(name)
    except (UnknownMazeError, MazeError) as e:
        typer.echo(f"error: {e}", err=True)
        raise typer.Exit(1) from None
    out.parent.mkdir(parents=True, exist_ok=True)
    try:
        written = cv2.imwrite(str(out), maze.image(walls_only=walls_only))
    except cv2.error:
        written = False
    if not written:
        typer.echo(f"error: could not write {out} (use a .png name)", err=True)
        raise typer.Exit(1)
    typer.echo(f"wrote {out}")

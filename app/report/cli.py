"""`robotslang report agreement --study NAME [--json]` and
`robotslang report study --study NAME [--benchmark PATH] --out DIR`."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

import typer

if TYPE_CHECKING:  # the database loads only for the commands that use it
    from sqlalchemy.orm import Session, sessionmaker

    from app.settings import Settings


def register(root: typer.Typer) -> None:
    app = typer.Typer(help="Reports on a study: annotators' agreement, the dataset section.", no_args_is_help=True)
    app.command("agreement")(agreement)
    app.command("study")(study)
    root.add_typer(app, name="report")


def _database() -> tuple[Settings, sessionmaker[Session]]:
    from app.db.engine import make_engine, make_sessionmaker
    from app.settings import Settings

    settings = Settings()
    if settings.database_url is None and not settings.sqlite_path.exists():
        typer.echo(f"error: no database at {settings.sqlite_path}: set ROBOTSLANG_DATA_DIR", err=True)
        raise typer.Exit(1)
    return settings, make_sessionmaker(make_engine(settings))


def agreement(
    study: str = typer.Option(..., "--study", help="The study's name (trials with trial.study == NAME)."),
    as_json: bool = typer.Option(False, "--json", help="Print the numbers as JSON."),
) -> None:
    """Cohen's kappa per phenomenon and the distance between localization cuts, over the trials
    two annotators submitted, and the disagreements (with the adjudicated value, if any)."""
    from app.annotation.agreement import answer_word
    from app.annotation.events import TITLES
    from app.annotation.log import AnnotationLog
    from app.annotation.study import study_agreement

    _, sessions = _database()
    with sessions() as db:
        result = study_agreement(db, AnnotationLog(sessions), study)
    if as_json:
        typer.echo(json.dumps({"study": study, **result}, indent=1))
        return
    typer.echo(f"study {study}: {result['double_annotated_trials']} trials annotated twice")
    for tag, k in result["kappa"].items():
        typer.echo(f"  kappa {TITLES.get(tag, tag)}: {'n/a' if k is None else f'{k:.3f}'}")
    cut = result["cut_distance"]
    mean = "n/a" if cut["mean"] is None else f"{cut['mean']:.2f}"
    typer.echo(f"  localization cut distance: mean {mean} messages, max {cut['max']}")
    for d in result["disagreements"]:
        said = "; ".join(f"{name}: {answer_word(v)}" for name, v in d["values"].items())
        typer.echo(
            f"  disagreement trial {d['trial']} {d['item']}: {said} (adjudicated: {answer_word(d['adjudicated'])})"
        )


def study(
    study: str | None = typer.Option(None, "--study", help="The study's name (trials with trial.study == NAME)."),
    benchmark: Path | None = typer.Option(
        None, "--benchmark", help="A benchmark clone: its mazes join the library; alone, report on its dialogs."
    ),
    out: Path = typer.Option(..., "--out", help="Folder for study.md, study.json and the PNG figures."),
) -> None:
    """The paper's dataset section for a study (or, with --benchmark alone, for the public
    benchmark beside the paper's numbers): Markdown, PNG figures and a JSON of every number."""
    from app.mazes import Mazes
    from app.report import figures
    from app.report.markdown import benchmark_markdown, study_markdown
    from app.settings import Settings

    if study is None and benchmark is None:
        typer.echo("error: give --study NAME, or --benchmark PATH for the public benchmark", err=True)
        raise typer.Exit(1)
    out.mkdir(parents=True, exist_ok=True)
    if study is None:
        from app.report.benchmark import benchmark_numbers

        assert benchmark is not None
        settings = Settings(benchmark=benchmark)
        public = benchmark_numbers(benchmark, Mazes(settings).layouts())
        markdown = benchmark_markdown(public)
        (out / "benchmark.json").write_text(json.dumps(public, indent=1))
        (out / "benchmark.md").write_text(markdown)
        typer.echo(markdown)
        return
    from app.report.study import study_numbers
    from app.study.config import StudyConfigError

    settings, sessions = _database()
    if benchmark is not None:
        settings = settings.model_copy(update={"benchmark": benchmark})
    try:
        numbers = study_numbers(sessions, settings, Mazes(settings), study)
    except (LookupError, StudyConfigError) as err:
        typer.echo(f"error: study {study!r}: {err}", err=True)
        raise typer.Exit(1) from None
    if not numbers["counts"]["trials"]:
        typer.echo(f"error: study {study!r} has no finished trials (not excluded)", err=True)
        raise typer.Exit(1)
    drawn = {
        "dialog_lengths": figures.dialog_lengths(numbers["dialog"], out / "dialog_lengths.png").name,
        "leaderboard": figures.leaderboard(numbers["leaderboard"], out / "leaderboard.png").name,
        "learning_curves": figures.learning_curves(numbers["leaderboard"], out / "learning_curves.png").name,
        "questionnaire": figures.questionnaire(numbers["questionnaire"]["items"], out / "questionnaire.png").name,
    }
    (out / "study.json").write_text(json.dumps(numbers, indent=1))
    (out / "study.md").write_text(study_markdown(numbers, drawn))
    typer.echo(
        f"study {study}: {numbers['counts']['trials']} trials, {numbers['messages_per_dialog']:.1f} messages and "
        f"{numbers['words_per_dialog']:.1f} words per dialog; wrote {out}/study.md, study.json and "
        f"{len(drawn)} figures"
    )

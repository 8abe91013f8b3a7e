"""`robotslang export TRIAL_ID|all --format mcap|ndh|lerobot --out PATH [--episode ndh|trial]
[--study NAME] [--folds train:val:test=70:15:15 --seed S]`."""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING

import typer
from rich.console import Console
from rich.progress import track

from app.export import Episode

if TYPE_CHECKING:  # the exporters load only for the command that runs
    from sqlalchemy.orm import Session, sessionmaker

    from app.export.record import TrialRecord
    from app.study.config import StudyFiles
    from sim.core.maze import Maze

console = Console(stderr=True)


class Format(StrEnum):
    mcap = "mcap"
    ndh = "ndh"
    lerobot = "lerobot"


def register(root: typer.Typer) -> None:
    root.command("export")(export)


def export(
    trial: str = typer.Argument(
        ..., metavar="TRIAL_ID|all", help="A trial's id, or `all` for every finished trial not excluded."
    ),
    format: Format = typer.Option(
        ..., "--format", help="mcap (Foxglove), ndh (benchmark JSON) or lerobot (LeRobotDataset v3)."
    ),
    out: Path = typer.Option(
        ...,
        "--out",
        help="MCAP: a file (one trial) or a folder; "
        "NDH: the folder to write the benchmark layout into; "
        "LeRobot: a new (or empty) dataset folder.",
    ),
    episode: Episode = typer.Option(
        Episode.ndh, "--episode", help="LeRobot: one episode per NDH instance (ndh) or per trial (trial)."
    ),
    include_aborted: bool = typer.Option(
        False, "--include-aborted", help="With `all`: aborted trials too, with what they recorded (targets confirmed)."
    ),
    study: str | None = typer.Option(None, "--study", help="With `all`: only this study's trials."),
    folds: str | None = typer.Option(
        None,
        "--folds",
        help="NDH: split the study's layouts into folds with these shares, e.g. train:val:test=70:15:15 "
        "(no layout in two folds); saved in the data directory (folds/<study>.json) and reused. "
        "A study's export without it keeps the study's saved split, or draws and saves the default one.",
    ),
    seed: int = typer.Option(0, "--seed", help="--folds: the seed of the draw."),
) -> None:
    """Export recorded trials from the data directory (ROBOTSLANG_DATA_DIR); with `all --study
    NAME`, the study's questionnaire answers (questionnaires.csv and .json in --out) and its
    participants' roster for paying them (participants.csv) too."""
    from app.db.engine import make_engine, make_sessionmaker
    from app.export.folds import DEFAULT_SHARES, FoldError, FoldShares, SavedFolds
    from app.export.record import ExportError
    from app.export.source import exported_trial_ids, load_trial
    from app.mazes import Mazes, UnknownMaze
    from app.settings import Settings

    settings = Settings()
    shares = None
    if folds is not None:
        if format is not Format.ndh or study is None or trial != "all":
            _fail("--folds splits a study's NDH and LDH export: give `all --format ndh --study NAME --folds ...`")
        try:
            shares = FoldShares.parse(folds)
        except FoldError as err:
            _fail(str(err))
    elif format is Format.ndh and study is not None and trial == "all":
        # The study's split is one, export after export: the saved one, else the default drawn and saved.
        saved = SavedFolds.of(settings.data_dir, study).load()
        shares, seed = saved[:2] if saved is not None else (FoldShares.parse(DEFAULT_SHARES), seed)
    if settings.database_url is None and not settings.sqlite_path.exists():
        _fail(
            f"no database at {settings.sqlite_path}: set ROBOTSLANG_DATA_DIR to the data "
            f"directory of a server that recorded trials (or run `robotslang demo`)"
        )
    sessions = make_sessionmaker(make_engine(settings))
    mazes = Mazes(settings)
    with sessions() as session:
        ids: list[int | str] = [*exported_trial_ids(session, include_aborted, study)] if trial == "all" else [trial]
        if not ids:
            which = "finished or aborted" if include_aborted else "finished"
            of_study = f" of study {study!r}" if study else ""
            _fail(f"no {which} trials{of_study} (not excluded) in {settings.url.split('@')[-1]}")
        try:
            records = [load_trial(session, settings, i) for i in ids]
        except ExportError as err:
            _fail(str(err))
    loaded: list[tuple[TrialRecord, Maze]] = []
    for record in records:
        try:
            loaded.append((record, mazes.load(record.maze)))
        except UnknownMaze:
            _fail(
                f"trial {record.trial_id}: maze {record.maze!r} is not in the maze library (the bundled "
                f"mazes, and the benchmark's when ROBOTSLANG_BENCHMARK points at it)"
            )
    try:
        if format is Format.ndh:
            from app.export.ndh import write_benchmark

            maze_folds = None
            if shares is not None and study is not None:
                layout_of = mazes.layouts()
                by_layout = SavedFolds.of(settings.data_dir, study).split(
                    {layout_of[r.maze] for r, _ in loaded}, shares, seed
                )
                maze_folds = {r.maze: by_layout[layout_of[r.maze]] for r, _ in loaded}
            summary = write_benchmark(track(loaded, description="NDH export", console=console), out, maze_folds)
            console.print(f"{summary.trials} trial(s) -> {out}: NDH {summary.ndh}, LDH {summary.ldh}")
        elif format is Format.lerobot:
            _export_lerobot(loaded, out, episode)
        else:
            _export_mcap(loaded, out, single=trial != "all")
    except (ExportError, FoldError) as err:
        _fail(str(err))
    if study is not None and trial == "all":
        _export_answers(sessions, settings.data_dir, study, out)


def _export_answers(sessions: sessionmaker[Session], data_dir: Path, study: str, out: Path) -> None:
    """The study's questionnaire answers beside its trials: a CSV, and a JSON with the items each
    study version asked."""
    import json

    from app.study.answers import answers_csv, answers_json, asked, items, study_answers
    from app.study.config import StudyConfigError, StudyFiles

    with sessions() as session:
        answers = study_answers(session, study)
    files = StudyFiles.of(data_dir)
    if not answers and study not in files.names():
        return  # trials given a study's name by hand, with no study file: nobody was asked anything
    _export_roster(sessions, files, study, out)
    try:
        questionnaires = asked(files, study, answers)
    except (LookupError, StudyConfigError) as err:
        _fail(f"the questionnaire answers need the study's file: {err}")
    out.mkdir(parents=True, exist_ok=True)
    (out / "questionnaires.csv").write_text(answers_csv(study, answers, items(questionnaires)))
    (out / "questionnaires.json").write_text(json.dumps(answers_json(study, answers, questionnaires), indent=1))
    console.print(f"{len(answers)} questionnaire answer(s) -> {out}/questionnaires.csv, questionnaires.json")


def _export_roster(sessions: sessionmaker[Session], files: StudyFiles, study: str, out: Path) -> None:
    """One row per participant for paying them (`app.study.roster`): participants.csv in --out."""
    from datetime import UTC, datetime

    from app.clock import ServerClock
    from app.study.config import StudyConfigError
    from app.study.enrolment import Enrolment
    from app.study.roster import roster, roster_csv

    try:
        config = files.load(study)
    except (LookupError, StudyConfigError) as err:
        _fail(f"the participants' roster needs the study's file: {err}")
    with sessions() as session:
        rows = roster(Enrolment(session, ServerClock(), config), datetime.now(UTC))
    out.mkdir(parents=True, exist_ok=True)
    (out / "participants.csv").write_text(roster_csv(rows))
    console.print(f"{len(rows)} participant(s) -> {out}/participants.csv")


def _export_mcap(loaded: list[tuple[TrialRecord, Maze]], out: Path, single: bool) -> None:
    from app.export.mcap import write_mcap

    if single and not out.is_dir():
        ((record, maze),) = loaded
        console.print(f"trial {record.trial_id} -> {write_mcap(record, maze, out)}")
        return
    for record, maze in track(loaded, description="MCAP export", console=console):
        write_mcap(record, maze, out / f"trial-{record.trial_id}.mcap")
    console.print(f"{len(loaded)} trial(s) -> {out}")


def _export_lerobot(loaded: list[tuple[TrialRecord, Maze]], out: Path, per: Episode) -> None:
    from app.export.lerobot import write_lerobot

    try:
        import av  # noqa: F401
        import pandas  # noqa: F401
        import pyarrow  # noqa: F401
    except ImportError as err:
        _fail(f"the LeRobot export needs the `lerobot` extra (pip install robotslang[lerobot]): {err}")
    totals = write_lerobot(track(loaded, description="LeRobot export", console=console), out, per)
    console.print(
        f"{len(loaded)} trial(s) -> {out}: {totals['episodes']} episode(s), "
        f"{totals['frames']} frame(s), {totals['tasks']} task(s)"
    )


def _fail(message: str) -> None:
    console.print(f"[red]error:[/red] {message}", soft_wrap=True)
    raise typer.Exit(1)

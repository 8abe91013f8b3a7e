"""`robotslang annotate assign --study NAME --annotator A --annotator B [--share 0.2] [--seed S]`."""

from __future__ import annotations

import typer


def register(root: typer.Typer) -> None:
    app = typer.Typer(help="Annotation of a study's trials (see docs/annotation.md).", no_args_is_help=True)
    app.command("assign")(assign)
    root.add_typer(app, name="annotate")


def assign(
    study: str = typer.Option(..., "--study", help="The study whose finished trials to assign."),
    annotators: list[str] = typer.Option(..., "--annotator", help="An annotator's account (repeat for each)."),
    share: float = typer.Option(0.2, "--share", help="Share of trials annotated twice (stratified by layout)."),
    seed: int = typer.Option(0, "--seed", help="Seed of the draw."),
) -> None:
    """Sample a share of the study's trials for double annotation and queue every trial not yet
    assigned: the sampled ones to two annotators, the others to one, in turn."""
    from app.annotation.assign import AssignmentError
    from app.annotation.assign import assign as assign_trials
    from app.db.engine import open_database
    from app.mazes import Mazes
    from app.settings import Settings

    settings = Settings()
    sessions = open_database(settings)
    layouts = Mazes(settings).layouts()
    try:
        with sessions.begin() as db:
            done = assign_trials(db, study, annotators, layouts, share, seed)
    except AssignmentError as err:
        typer.echo(f"error: {err}", err=True)
        raise typer.Exit(1) from None
    typer.echo(f"{len(done.double)} trials for two annotators, {len(done.single)} for one")
    for name, trial_ids in done.queues.items():
        typer.echo(f"{name}: {len(trial_ids)} trials ({' '.join(map(str, trial_ids))})")

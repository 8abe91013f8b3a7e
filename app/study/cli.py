"""`robotslang study purge [--study NAME]`: delete the personal data of the studies whose
`purge_after_days` since `closed_at` have passed (docs/study.md)."""

from __future__ import annotations

import typer


def register(root: typer.Typer) -> None:
    app = typer.Typer(help="Participant studies (see docs/study.md).", no_args_is_help=True)
    app.command("purge")(purge)
    root.add_typer(app, name="study")


def purge(
    study: str | None = typer.Option(None, "--study", help="Only this study (default: every study)."),
) -> None:
    """Delete the personal data (real names, free text, panel identifiers) of each study closed
    `purge_after_days` ago or more; the server does the same at each start."""
    from datetime import UTC, datetime

    from app.clock import ServerClock
    from app.db.engine import open_database
    from app.settings import Settings
    from app.study.config import StudyConfigError, StudyFiles
    from app.study.purge import purge_due

    settings = Settings()
    files = StudyFiles.of(settings.data_dir)
    if study is not None:
        try:
            files.load(study)
        except (LookupError, StudyConfigError) as err:
            typer.echo(f"error: {err}", err=True)
            raise typer.Exit(1) from None
    names = files.names() if study is None else [study]
    with open_database(settings).begin() as db:
        purged = purge_due(db, files, ServerClock(), datetime.now(UTC), names)
    for name in names:
        if name in purged:
            typer.echo(f"{name}: personal data of {purged[name]} participant(s) deleted")
        else:
            typer.echo(f"{name}: not due (closed_at + purge_after_days not reached, or not set)")

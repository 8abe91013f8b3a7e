"""`robotslang serve|admin|db` (and `export`/`demo`, mounted from their packages)."""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Optional

import typer

# Packages under app/ that bring their own commands, each with `register(root)`.
MOUNTED = ("app.export.cli", "app.demo.cli", "app.robot_commands")


def serve(host: str = typer.Option("127.0.0.1", help="Interface to listen on."),
          port: int = typer.Option(8000, help="TCP port."),
          data_dir: Optional[Path] = typer.Option(None, "--data-dir", help="Database, frames and secret key "
                                                  "(default ROBOTSLANG_DATA_DIR, else ./var)."),
          benchmark: Optional[Path] = typer.Option(None, "--benchmark", help="A RobotSlangBenchmark clone whose "
                                                   "mazes join the bundled ones (default ROBOTSLANG_BENCHMARK).")
          ) -> None:
    """Serve the platform (pages, trial sockets) on HOST:PORT."""
    import uvicorn

    from app.main import create_app
    from app.settings import Settings

    # Flags override the environment; what is not given keeps its ROBOTSLANG_* value.
    overrides = {name: value for name, value in (("data_dir", data_dir), ("benchmark", benchmark))
                 if value is not None}
    settings = Settings(**overrides)
    app = create_app(settings)
    typer.echo(f"RobotSlang on http://{host}:{port} (data in {settings.data_dir.resolve()})")
    # Frames and claims are sent inline; keep the transport limit above the message limit so an
    # oversized message gets an error reply instead of a closed socket. No per-message deflate:
    # the largest messages are JPEGs, which do not compress, and deflating them costs CPU.
    from app.backends.remote import MAX_FRAME_BYTES  # the rover's camera frames are the largest messages

    uvicorn.run(app, host=host, port=port, log_level="warning",
                ws_max_size=max(65536, 4 * settings.max_message_bytes, 2 * MAX_FRAME_BYTES),
                ws_per_message_deflate=False)


def admin_create(name: str = typer.Argument(..., help="The experimenter's login name."),
                 password: Optional[str] = typer.Option(None, help="Prompted for when not given.")) -> None:
    """Create an experimenter account (or set the password of an existing one)."""
    from sqlalchemy import select

    from app.db.engine import open_database
    from app.db.models import Experimenter
    from app.security import hash_password
    from app.settings import Settings

    if not name.strip() or len(name) > 80:
        raise typer.BadParameter("must be 1 to 80 characters", param_hint="NAME")
    if password is None:
        password = typer.prompt("Password", hide_input=True, confirmation_prompt=True)
    if len(password) < 8:
        raise typer.BadParameter("must be at least 8 characters", param_hint="--password")
    with open_database(Settings()).begin() as db:
        user = db.scalar(select(Experimenter).where(Experimenter.name == name))
        if user is None:
            db.add(Experimenter(name=name, password_hash=hash_password(password)))
            typer.echo(f"experimenter {name!r} created")
        else:
            user.password_hash = hash_password(password)
            typer.echo(f"experimenter {name!r}: password changed")


def db_upgrade() -> None:
    """Bring the database (ROBOTSLANG_DATABASE_URL, else the SQLite file in the data dir) up to date."""
    from app.db.engine import upgrade
    from app.settings import Settings

    settings = Settings()
    upgrade(settings)
    typer.echo(f"database at {settings.url.split('@')[-1]} is up to date")


def register(root: typer.Typer) -> None:
    """Mount the server's commands on the root CLI."""
    root.command("serve")(serve)
    admin = typer.Typer(help="Experimenter accounts.", no_args_is_help=True)
    admin.command("create")(admin_create)
    root.add_typer(admin, name="admin")
    db = typer.Typer(help="The database.", no_args_is_help=True)
    db.command("upgrade")(db_upgrade)
    root.add_typer(db, name="db")
    for module in MOUNTED:
        importlib.import_module(module).register(root)

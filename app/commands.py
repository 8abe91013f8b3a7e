"""`robotslang serve|drivers|admin|db`, `mazes prepare` (and `export`/`demo`, mounted from their packages)."""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer

if TYPE_CHECKING:
    from app.security import AccountRole

# Packages under app/ that bring their own commands, each with `register(root)`.
MOUNTED = ("app.export.cli", "app.demo.cli", "app.rover.commands", "app.study.cli")

BENCHMARK_OPTION = typer.Option(
    None,
    "--benchmark",
    help="A RobotSlangBenchmark clone whose mazes join the bundled ones (default ROBOTSLANG_BENCHMARK).",
)


def serve(
    host: str = typer.Option("127.0.0.1", help="Interface to listen on."),
    port: int = typer.Option(8000, help="TCP port."),
    data_dir: Path | None = typer.Option(
        None, "--data-dir", help="Database, frames and secret key (default ROBOTSLANG_DATA_DIR, else ./var)."
    ),
    benchmark: Path | None = BENCHMARK_OPTION,
    workers: int = typer.Option(
        1, min=1, help="Server processes sharing trials (over 1: needs ROBOTSLANG_REDIS_URL; see docs/platform.md)."
    ),
) -> None:
    """Serve the platform (pages, trial sockets) on HOST:PORT: one process (`make run`: SQLite, no
    Redis), or `workers` processes sharing one listening socket; they share trials through Redis
    and one database (`app.trial.relay`), each trial run by one process at a time."""
    import os

    import uvicorn

    from app.main import create_app
    from app.serving import log_config, uvicorn_options
    from app.settings import Settings

    # Flags override the environment (in every worker too); what is not given keeps its ROBOTSLANG_* value.
    overrides: dict[str, Any] = {
        name: value for name, value in (("data_dir", data_dir), ("benchmark", benchmark)) if value is not None
    }
    settings = Settings(**overrides)
    if "FORWARDED_ALLOW_IPS" in os.environ:
        raise typer.BadParameter(
            "FORWARDED_ALLOW_IPS is not read: name the proxies in ROBOTSLANG_TRUSTED_PROXIES (addresses or networks)"
        )
    for name, value in overrides.items():  # each worker reads its settings from the environment
        os.environ[f"ROBOTSLANG_{name.upper()}"] = str(value)
    if workers > 1 and not settings.redis_url:
        raise typer.BadParameter(
            "several workers share trials through Redis: set ROBOTSLANG_REDIS_URL", param_hint="--workers"
        )
    typer.echo(
        f"RobotSlang on http://{host}:{port} (data in {settings.data_dir.resolve()}"
        f"{f', {workers} processes' if workers > 1 else ''})"
    )
    options = {
        "host": host,
        "port": port,
        "log_level": "warning",
        "log_config": log_config(),
        **uvicorn_options(settings),
    }
    if workers == 1:
        uvicorn.run(create_app(settings), **options)
    else:  # each worker builds its own app from the same environment
        create_app(settings)  # upgrade the database once, before the workers race to
        uvicorn.run("app.main:create_app", factory=True, workers=workers, **options)


def mazes_prepare(
    benchmark: Path | None = BENCHMARK_OPTION,
    cache_dir: Path | None = typer.Option(
        None, "--cache-dir", help="Where to prepare them (default ROBOTSLANG_CACHE_DIR, else ~/.cache/robotslang)."
    ),
) -> None:
    """Prepare what trials need of every maze (graphs, all-pairs and ray tables, render scenes) in
    the cache, as a server does in the background from its start."""
    from concurrent.futures import as_completed

    from rich.progress import track

    from app.preparation import build_maze, builder_pool, builders_for
    from app.settings import Settings
    from sim.core.maze import MazeError
    from sim.tasks.library import MazeLibrary

    overrides: dict[str, Any] = {
        name: value for name, value in (("benchmark", benchmark), ("cache_dir", cache_dir)) if value is not None
    }
    settings = Settings(**overrides)
    try:
        library = MazeLibrary(settings.benchmark, cache=False, cache_dir=settings.cache_dir)
        names = library.names()
    except FileNotFoundError as err:
        raise typer.BadParameter(str(err), param_hint="--benchmark") from None
    built, failed = 0, []
    with builder_pool(settings.benchmark, settings.cache_dir, builders_for(settings.maze_builders)) as pool:
        building = {pool.submit(build_maze, name): name for name in names}
        for done in track(as_completed(building), total=len(names), description="Preparing mazes"):
            try:
                built += done.result()
            except MazeError as err:
                failed.append(building[done])
                typer.echo(f"error: {err}", err=True)
    ready = len(names) - len(failed)
    typer.echo(f"{ready} of {len(names)} mazes ready in {settings.cache_dir} ({built} prepared now)")
    if failed:
        raise typer.Exit(1)


def admin_create(
    name: str = typer.Argument(..., help="The account's login name."),
    password: str | None = typer.Option(None, help="Prompted for when not given."),
    role: str = typer.Option(
        "experimenter", "--role", help="experimenter, or annotator (sees only the annotation pages, never names)."
    ),
) -> None:
    """Create an account (or set the password of an existing one)."""
    from app.security import AccountRole

    if role not in tuple(AccountRole):
        raise typer.BadParameter(f"must be one of {', '.join(AccountRole)}", param_hint="--role")
    _set_password(name, password, create=True, role=AccountRole(role))


def admin_password(
    name: str = typer.Argument(..., help="The experimenter's login name."),
    password: str | None = typer.Option(None, help="Prompted for when not given."),
) -> None:
    """Change an experimenter's password; the account's logins end everywhere."""
    _set_password(name, password, create=False)


def _set_password(name: str, password: str | None, create: bool, role: AccountRole | None = None) -> None:
    from sqlalchemy import select

    from app.accounts import MIN_PASSWORD, AccountError, check_password, create_account
    from app.db.engine import open_database
    from app.db.models import Experimenter
    from app.security import AccountRole, set_password
    from app.settings import Settings

    if not name.strip() or len(name) > 80:
        raise typer.BadParameter("must be 1 to 80 characters", param_hint="NAME")
    db_sessions = open_database(Settings())
    with db_sessions() as db:
        exists = db.scalar(select(Experimenter.id).where(Experimenter.name == name)) is not None
    if not exists and not create:
        raise typer.BadParameter(
            f"no experimenter {name!r} (create one with `robotslang admin create`)", param_hint="NAME"
        )
    if password is None:
        password = typer.prompt("Password", hide_input=True, confirmation_prompt=True)
    try:
        check_password(password)
    except AccountError:
        raise typer.BadParameter(f"must be at least {MIN_PASSWORD} characters", param_hint="--password") from None
    with db_sessions.begin() as db:
        user = db.scalar(select(Experimenter).where(Experimenter.name == name))
        if user is None:
            user = create_account(db, name, password, role or AccountRole.EXPERIMENTER)
        elif role is not None and user.role != role:
            raise typer.BadParameter(f"{name!r} exists as an {user.role}, not an {role}", param_hint="NAME")
        else:
            set_password(user, password)
        kind = user.role
    typer.echo(f"{kind} {name!r} " + ("created" if not exists else "password changed; its logins have ended"))


def db_upgrade() -> None:
    """Bring the database (ROBOTSLANG_DATABASE_URL, else the SQLite file in the data dir) up to date."""
    from app.db.engine import upgrade
    from app.settings import Settings

    settings = Settings()
    upgrade(settings)
    typer.echo(f"database at {settings.url.split('@')[-1]} is up to date")


def drivers() -> None:
    """Who can drive a trial: `human`, and each agent (`agent:`) or cheating baseline (`oracle:`),
    with why it cannot start here where it cannot, and the caps on an agent Driver."""
    from app.main import build_services
    from app.seats.registry import available_drivers
    from app.settings import Settings

    services = build_services(Settings())
    try:
        available = available_drivers(services.agents)
    finally:
        services.engine.dispose()
    typer.echo("human")
    for spec, reason in available.items():
        typer.echo(f"{spec}" + (f"  (unavailable: {reason})" if reason else ""))
    s = services.settings
    typer.echo(
        f"an agent Driver stops after {s.agent_moves_per_target} moves per target or "
        f"{s.agent_minutes_per_trial:g} minutes of trial clock, an agent in either seat after "
        f"{s.agent_messages_per_target} of its own messages on one target (ROBOTSLANG_AGENT_MOVES_PER_TARGET, "
        "ROBOTSLANG_AGENT_MINUTES_PER_TRIAL, ROBOTSLANG_AGENT_MESSAGES_PER_TARGET)"
    )


def register(root: typer.Typer, eval_app: typer.Typer) -> None:
    """Mount the server's commands on the root CLI."""
    from app import selfplay_cli  # offline self-play or through the trial core: it takes both layers

    eval_app.command("selfplay")(selfplay_cli.eval_selfplay)
    root.command("serve")(serve)
    root.command("drivers")(drivers)
    from sim.cli.mazes import app as mazes_app  # the library's commands, and this one that prepares it for the server

    mazes_app.command("prepare")(mazes_prepare)
    admin = typer.Typer(help="Experimenter accounts.", no_args_is_help=True)
    admin.command("create")(admin_create)
    admin.command("password")(admin_password)
    root.add_typer(admin, name="admin")
    db = typer.Typer(help="The database.", no_args_is_help=True)
    db.command("upgrade")(db_upgrade)
    root.add_typer(db, name="db")
    for module in MOUNTED:
        importlib.import_module(module).register(root)

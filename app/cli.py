"""The `robotslang` command line: one root that mounts each package's commands.

Each package owns its commands (sim/cli.py, models/cli.py, app/commands.py); this module only
assembles them, so that `robotslang --help` starts fast and torch is imported only by the
commands that need it.
"""

from __future__ import annotations

import typer

from app import bench_cli
from app import commands as app_commands
from app.annotation import cli as annotation_commands
from app.report import cli as report_commands
from models import cli as model_commands
from sim import cli as sim_commands

root = typer.Typer(
    help="RobotSlang: dialog-guided robot localization and navigation.", no_args_is_help=True, add_completion=False
)
eval_app = typer.Typer(help="Evaluate agents on the benchmark's NDH instances.", no_args_is_help=True)


def installed_version() -> str:
    from importlib.metadata import PackageNotFoundError, version  # a quarter second: only for --version

    try:
        return version("robotslang")
    except PackageNotFoundError:  # a checkout on PYTHONPATH, not installed
        return "unknown (not installed)"


def show_version(value: bool) -> None:
    if value:
        typer.echo(f"robotslang {installed_version()}")
        raise typer.Exit()


@root.callback()
def _root(
    version_: bool | None = typer.Option(
        None, "--version", callback=show_version, is_eager=True, help="Print the installed version and exit."
    ),
) -> None:
    """RobotSlang: dialog-guided robot localization and navigation."""


sim_commands.register(root, eval_app)
model_commands.register(root, eval_app)
app_commands.register(root, eval_app)
bench_cli.register(root)
annotation_commands.register(root)
report_commands.register(root)
root.add_typer(eval_app, name="eval")


def main() -> None:
    try:
        root()
    except ModuleNotFoundError as err:
        if err.name != "torch":
            raise
        typer.echo(
            "error: this command needs PyTorch, which the server and simulator do without: "
            "pip install 'robotslang[learn]' (the README says how to get its CPU build)",
            err=True,
        )
        raise SystemExit(1) from None


if __name__ == "__main__":
    main()

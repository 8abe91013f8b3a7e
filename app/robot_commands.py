"""`robotslang robot create|list`: register rovers and overhead cameras from the command line.

The token is printed once, at creation; the database keeps only its hash, so a lost token
means registering the robot again under a new name.
"""

from __future__ import annotations

import typer

from app.backends.remote import ROBOT_ROLES


def _sessions():
    from app.db.engine import open_database
    from app.settings import Settings

    return open_database(Settings())


def robot_create(name: str = typer.Argument(..., help="The robot's name, unique on this server."),
                 role: str = typer.Option("driver", help=f"One of: {', '.join(ROBOT_ROLES)} "
                                                         "(the rover, or the camera over the table).")) -> None:
    """Register a robot and print its token (shown only this once)."""
    from app.backends.remote import RobotSetupError, create_robot

    if len(name) > 80:
        raise typer.BadParameter("must be at most 80 characters", param_hint="NAME")
    try:
        with _sessions().begin() as db:
            robot, token = create_robot(db, name, role)
            robot_id, robot_name, robot_role = robot.id, robot.name, robot.role
    except RobotSetupError as err:
        raise typer.BadParameter(str(err), param_hint="--role" if "role" in str(err) else "NAME") from None
    uses = f"trials use it as backend robot:{robot_id}" if robot_role == "driver" else "recorded into trials on a rover"
    typer.echo(f"robot {robot_name!r} ({robot_role}) registered; {uses}")
    typer.echo("token (shown only this once; the server keeps its hash):")
    typer.echo(token)
    extra = "" if robot_role == "driver" else f" --role {robot_role}"
    typer.echo(f"on the robot: robotslang-robot --server URL --token {token}{extra}")


def robot_list() -> None:
    """Every registered robot: id, role, trial backend and name (tokens are never shown again)."""
    from sqlalchemy import select

    from app.db.models import Robot

    with _sessions()() as db:
        robots = db.scalars(select(Robot).order_by(Robot.name)).all()
        if not robots:
            typer.echo("no robots registered (robotslang robot create NAME)")
        for robot in robots:
            backend = f"robot:{robot.id}" if robot.role == "driver" else "-"
            typer.echo(f"{robot.id:>4}  {robot.role:<8}  {backend:<10}  {robot.name}")


def register(root: typer.Typer) -> None:
    robot = typer.Typer(help="Robots (rovers and overhead cameras) and their tokens.", no_args_is_help=True)
    robot.command("create")(robot_create)
    robot.command("list")(robot_list)
    root.add_typer(robot, name="robot")

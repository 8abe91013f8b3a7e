"""`robotslang robot create|list|calibrate-overhead|virtual`: register rovers and overhead cameras,
measure the overhead camera's view of the table, and run a software rover or overhead camera.

The token is printed once, at creation; the database keeps only its hash, so a lost token
means registering the robot again under a new name.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import typer

from sim.trial.specs import BackendSpec
from sim.trial.vocabulary import ROBOT_ROLES

if TYPE_CHECKING:  # the database and numpy load only for the commands that use them
    import numpy as np
    from sqlalchemy.orm import Session, sessionmaker

T = TypeVar("T")


def _sessions() -> sessionmaker[Session]:
    from app.db.engine import open_database
    from app.settings import Settings

    return open_database(Settings())


def robot_create(
    name: str = typer.Argument(..., help="The robot's name, unique on this server."),
    role: str = typer.Option(
        "driver", help=f"One of: {', '.join(ROBOT_ROLES)} (the rover, or the camera over the table)."
    ),
) -> None:
    """Register a robot and print its token (shown only this once)."""
    from app.rover.records import RobotSetupError, create_robot

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
            backend = str(BackendSpec.robot(robot.id)) if robot.role == "driver" else "-"
            typer.echo(f"{robot.id:>4}  {robot.role:<8}  {backend:<10}  {robot.name}")


def robot_virtual(
    server: str = typer.Option(..., help="Server URL, e.g. http://127.0.0.1:8000."),
    token: str = typer.Option(
        ...,
        envvar="ROBOTSLANG_ROBOT_TOKEN",
        help="The robot's token from `robotslang robot create` (or ROBOTSLANG_ROBOT_TOKEN).",
    ),
    maze: str = typer.Option(..., help="The maze on the table (a name from `robotslang mazes list`)."),
    role: str = typer.Option("driver", help="driver: the rover (motors, front camera); overhead: the table camera."),
    seed: int = typer.Option(0, help="Seeds the start pose, the motion errors and the camera noise."),
    noise: str = typer.Option("default", help="Motion error of each pulse: default or none (exact moves)."),
    truth: Path | None = typer.Option(
        None, help="Driver: write the true pose here (JSON lines); overhead: the driver rover's file to film."
    ),
    start: str | None = typer.Option(
        None, help="Start pose X,Y,THETA (metres, metres, radians); default a random node, from --seed."
    ),
    fps: float | None = typer.Option(
        None, help="Camera frames per second, 0.5..60 [default: 15 for the rover, 5 for the overhead camera]."
    ),
    calibration: Path | None = typer.Option(
        None, help="Move timings as `robotslang-robot calibrate` writes them (default: the client's defaults)."
    ),
) -> None:
    """Run a software rover (or overhead camera) through the real rover client's link."""
    import sys

    from app.mazes import Mazes, UnknownMaze
    from app.rover.virtual.command import VirtualRoverSpec, parse_start, run
    from app.settings import Settings
    from robot_client.calibration import Calibration, CalibrationError
    from robot_client.client import robot_url
    from sim.robot.rover import MotionNoise, Rover

    if role not in ROBOT_ROLES:
        raise typer.BadParameter(f"expected one of {', '.join(ROBOT_ROLES)}, got {role!r}", param_hint="--role")
    fps = fps if fps is not None else (15.0 if role == "driver" else 5.0)
    if not 0.5 <= fps <= 60:
        raise typer.BadParameter(f"must be 0.5..60 frames per second, got {fps}", param_hint="--fps")

    def checked(hint: str, read: Callable[[], T]) -> T:
        try:
            return read()
        except (ValueError, CalibrationError) as err:
            raise typer.BadParameter(str(err), param_hint=hint) from None

    checked("--server", lambda: robot_url(server))
    motion_noise = checked("--noise", lambda: MotionNoise.named(noise))
    start_pose = checked("--start", lambda: parse_start(start) if start else None)
    timings = checked("--calibration", lambda: Calibration.load(calibration) if calibration else None)
    mazes = Mazes(Settings())
    try:
        table = mazes.load(maze)
    except UnknownMaze as err:
        raise typer.BadParameter(f"{err}; known: {', '.join(mazes.names()[:8])}, ...", param_hint="--maze") from None
    if role == "overhead" and truth is None:
        raise typer.BadParameter(
            "the overhead camera films the driver rover's truth file: give its path", param_hint="--truth"
        )
    checked("--start", lambda: Rover(table, start_pose) if start_pose else None)  # the rover fits there
    spec = VirtualRoverSpec(
        server=server,
        token=token,
        maze=table,
        role=role,
        seed=seed,
        noise=motion_noise,
        truth=truth,
        start=start_pose,
        fps=fps,
        calibration=timings or Calibration(),
    )
    graph = mazes.graph(maze) if role == "driver" and spec.start is None else None
    sys.exit(run(spec, graph))


def calibrate_overhead(
    camera: str = typer.Option(None, help="The overhead camera: an OpenCV index (0), a video file or a URL."),
    image: Path = typer.Option(None, help="Calibrate from this image file instead of a camera."),
    out: Path = typer.Option(
        None,
        help="Where to write the calibration (default: the overhead_calibration "
        "setting, DATA_DIR/overhead_calibration.json).",
    ),
    fov: float = typer.Option(
        None, help="The camera's horizontal field of view in degrees (default: measured from the markers)."
    ),
) -> None:
    """Measure the table -> image homography from the four corner markers and store it."""
    from app.settings import Settings
    from sim.robot.calibration import CalibrationError
    from sim.robot.tracking import calibrate

    if (camera is None) == (image is None):
        raise typer.BadParameter("give exactly one of --camera and --image", param_hint="--camera")
    frame = _read_image(image) if image is not None else _grab_frame(camera)
    try:
        calibration = calibrate(frame, fov_deg=fov)
    except CalibrationError as err:
        typer.echo(f"error: {err}", err=True)
        raise typer.Exit(1) from None
    target = out or Settings().overhead_calibration
    assert target is not None  # Settings fills in its default, DATA_DIR/overhead_calibration.json
    path = calibration.save(target)
    focal = calibration.camera_matrix[0, 0]
    width, height = calibration.image_size
    typer.echo(
        f"calibrated {width}x{height} frames: corner markers fit to {calibration.reprojection_px:.2f} px RMS, "
        f"focal length {focal:.0f} px; written to {path}"
    )


def calibrate_camera(
    virtual: bool = typer.Option(
        False, "--virtual", help="The virtual rover's camera: colours learned from its renders on bundled mazes."
    ),
    frames: Path = typer.Option(
        None,
        help="A folder of the rover's frames taken at known poses on a known maze: its poses.json lists "
        '[{"image": "f1.jpg", "x": 0.5, "y": 0.4, "heading_deg": 90}, ...] (metres, table frame).',
    ),
    maze: str = typer.Option(None, help="--frames: the maze the frames were taken on (a library name)."),
    geometry: Path = typer.Option(
        None,
        help="--frames: a camera calibration JSON whose lens and mounting to keep (default: the rover's "
        "standard Pi camera, as robot_client mounts it).",
    ),
    out: Path = typer.Option(
        None,
        help="Where to write it (default: the camera_calibration setting, DATA_DIR/camera_calibration.json).",
    ),
) -> None:
    """Calibrate the rover's front camera for perception: its geometry and the colours of the walls
    and objects, which the particle filter and agent Drivers read rays with."""
    from app.settings import Settings
    from sim.robot.calibration import CalibrationError
    from sim.robot.camera import CameraCalibration, FrontCamera
    from sim.robot.perception import PerceptionError

    if virtual == (frames is not None):
        raise typer.BadParameter("give exactly one of --virtual and --frames", param_hint="--virtual")
    settings = Settings()
    try:
        if virtual:
            from app.perception.cameras import learned

            calibration = learned(FrontCamera(), progress=True)
        else:
            if maze is None:
                raise typer.BadParameter("--frames needs the maze they were taken on", param_hint="--maze")
            base = CameraCalibration.load(geometry) if geometry is not None else FrontCamera().calibration()
            calibration = _calibrated_from_frames(frames, maze, base, settings)
    except (CalibrationError, PerceptionError) as err:
        typer.echo(f"error: {err}", err=True)
        raise typer.Exit(1) from None
    target = out or settings.camera_calibration
    assert target is not None  # Settings fills in its default, DATA_DIR/camera_calibration.json
    path = calibration.save(target)
    typer.echo(f"camera calibrated: {len(calibration.colours)} colour classes; written to {path}")


def _calibrated_from_frames(folder: Path, maze_name: str, base: Any, settings: Any) -> Any:
    import json
    import math

    from app.mazes import Mazes, UnknownMaze
    from sim.core.observations import cast_rays
    from sim.robot.calibration import CalibrationError
    from sim.robot.perception import calibrate_colours

    try:
        maze = Mazes(settings).load(maze_name)
    except UnknownMaze:
        raise typer.BadParameter(f"{maze_name!r} is not in the maze library", param_hint="--maze") from None
    listing = folder / "poses.json"
    try:
        poses = json.loads(listing.read_text())
        images = [_read_image(folder / p["image"]) for p in poses]
        truths = [cast_rays(maze, float(p["x"]), float(p["y"]), math.radians(float(p["heading_deg"]))) for p in poses]
    except (OSError, ValueError, KeyError, TypeError) as err:
        raise CalibrationError(f"{listing}: {err}") from None
    return calibrate_colours(images, truths, base)


def _read_image(path: Path) -> np.ndarray:
    import cv2

    frame = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if frame is None:
        raise typer.BadParameter(f"{path}: not a readable image", param_hint="--image")
    return frame


def _grab_frame(camera: str) -> np.ndarray:
    import cv2

    capture = cv2.VideoCapture(int(camera) if camera.isdigit() else camera)
    frame = None
    try:
        for _ in range(5):  # a webcam's first frames are often dark while its exposure settles
            ok, grabbed = capture.read()
            if not ok:
                break
            frame = grabbed
    finally:
        capture.release()
    if frame is None:
        raise typer.BadParameter(f"{camera}: no frame from this camera", param_hint="--camera")
    return frame


def register(root: typer.Typer) -> None:
    robot = typer.Typer(help="Robots (rovers and overhead cameras) and their tokens.", no_args_is_help=True)
    robot.command("create")(robot_create)
    robot.command("list")(robot_list)
    robot.command("calibrate-overhead")(calibrate_overhead)
    robot.command("calibrate-camera")(calibrate_camera)
    robot.command("virtual")(robot_virtual)
    root.add_typer(robot, name="robot")

"""`robotslang-robot`: run the rover (`--server URL --token TOKEN ...`) or `calibrate` it."""

from __future__ import annotations

import argparse
import asyncio
import logging
import os
import signal
import sys
from pathlib import Path

from robot_client.calibration import Calibration, CalibrationError
from robot_client.camera import CameraError, CameraSettings, FrameGrabber, open_camera
from robot_client.client import LinkRefused, LinkSettings, RobotClient, robot_url
from robot_client.motors import MotorError, open_motors
from robot_client.protocol import ROLES

DEFAULT_CALIBRATION = Path.home() / ".config" / "robotslang" / "calibration.json"


def run_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="robotslang-robot",
        description="Stream the rover's camera to a RobotSlang server and execute the Driver's moves. "
        "`robotslang-robot calibrate --help` measures the moves.",
    )
    p.add_argument("--server", required=True, help="server URL, e.g. http://192.168.1.10:8000")
    p.add_argument(
        "--token",
        default=os.environ.get("ROBOTSLANG_ROBOT_TOKEN"),
        help="this robot's token from the experimenter page (or ROBOTSLANG_ROBOT_TOKEN)",
    )
    p.add_argument(
        "--role",
        choices=ROLES,
        default="driver",
        help="driver: the rover's front camera and motors; overhead: the table camera, no motors",
    )
    p.add_argument("--camera", default="0", help="0, 1, ... (USB webcam), picamera, synthetic, or a video file")
    p.add_argument("--motors", choices=("gpio", "mock"), default="gpio")
    p.add_argument(
        "--calibration",
        type=Path,
        default=DEFAULT_CALIBRATION,
        help=f"calibration JSON (default {DEFAULT_CALIBRATION}); with --motors mock the "
        "defaults are used when it does not exist",
    )
    p.add_argument("--width", type=int, default=640)
    p.add_argument("--height", type=int, default=480)
    p.add_argument("--fps", type=float, default=15.0)
    p.add_argument("--quality", type=int, default=80, help="JPEG quality 1..100")
    p.add_argument(
        "--watchdog",
        type=float,
        default=0.5,
        help="stop the motors after this many seconds without news from the server",
    )
    p.add_argument("--pin-log", type=Path, help="with --motors mock: append every pin change to this JSON-lines file")
    p.add_argument("-v", "--verbose", action="store_true")
    return p


def calibrate_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="robotslang-robot calibrate",
        description="Measure the pulse lengths of a 0.07 m step and 45 degree turns and write the calibration file.",
    )
    p.add_argument("--calibration", type=Path, default=DEFAULT_CALIBRATION, help="file to update or create")
    p.add_argument("--motors", choices=("gpio", "mock"), default="gpio")
    p.add_argument("--left-pins", type=pin_pair, help="BCM pins FORWARD,BACKWARD of the left motor")
    p.add_argument("--right-pins", type=pin_pair, help="BCM pins FORWARD,BACKWARD of the right motor")
    return p


def pin_pair(text: str) -> tuple[int, int]:
    try:
        forward, backward = (int(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected two BCM pin numbers like 4,14, got {text!r}") from None
    return forward, backward


def main(argv: list[str] | None = None) -> None:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["calibrate"]:
        args = calibrate_parser().parse_args(argv[1:])
        from robot_client import calibrate

        try:
            calibrate.run(args.motors, args.calibration, args.left_pins, args.right_pins)
        except (CalibrationError, MotorError) as exc:
            sys.exit(f"error: {exc}")
        except (KeyboardInterrupt, EOFError):
            sys.exit("\ncalibration abandoned; the file was not changed")
        return
    parser = run_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO, format="%(asctime)s %(levelname)s %(message)s"
    )
    if not args.token:
        parser.error("--token is required (or set ROBOTSLANG_ROBOT_TOKEN)")
    try:
        robot_url(args.server)
        settings = LinkSettings(server=args.server, token=args.token, role=args.role, watchdog_s=args.watchdog)
        if not 0.05 <= args.watchdog <= 5:
            raise ValueError(f"--watchdog must be 0.05..5 seconds, got {args.watchdog}")
        camera_settings = CameraSettings(args.width, args.height, args.fps, args.quality)
        motors = None
        if args.role == "driver":
            calibration = (
                Calibration()
                if args.motors == "mock" and not args.calibration.exists()
                else Calibration.load(args.calibration)
            )
            motors = open_motors(args.motors, calibration, args.pin_log)
        camera = open_camera(args.camera, camera_settings)
    except (ValueError, CameraError, MotorError) as exc:  # CalibrationError is a ValueError
        parser.exit(2, f"error: {exc}\n")
    client = RobotClient(settings, FrameGrabber(camera, camera_settings), motors, camera_settings.info(args.camera))
    sys.exit(run(client))


def run(client: RobotClient) -> int:
    """`serve` the client, then close its motors and its camera, however it ended."""
    try:
        return asyncio.run(serve(client))
    finally:
        if client.motors is not None:
            client.motors.close()
        if client.grabber is not None:
            client.grabber.stop()


async def serve(client: RobotClient) -> int:
    """Run until a signal (exit 0), a refusal by the server (exit 3) or a camera failure (exit 4)."""
    main_task = asyncio.current_task()
    assert main_task is not None  # called from within asyncio.run
    loop = asyncio.get_running_loop()

    def shutdown(signame: str) -> None:
        client.stop_motors(f"{signame} received")  # first, before anything can go wrong
        main_task.cancel()

    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, shutdown, sig.name)
    try:
        await client.run()
    except asyncio.CancelledError:
        logging.getLogger("robotslang.robot").info("stopped")
        return 0
    except LinkRefused as exc:
        logging.getLogger("robotslang.robot").error("the server refused this robot: %s", exc)
        return 3
    except CameraError as exc:
        logging.getLogger("robotslang.robot").error("%s", exc)
        return 4
    return 0

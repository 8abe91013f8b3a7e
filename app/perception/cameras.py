"""The Driver camera of a trial's robot seat, as perception needs it (`CameraCalibration`).

- `sim`: the simulator backend's frames are the ideal first-person render (320x240, no lens
  distortion, no noise), so its geometry is exact; its colours, learned once from renders of
  the bundled mazes, ship beside this module (`sim_camera.json`; `python -m
  app.perception.cameras` writes it again).
- a rover: the lab's calibration file (setting `camera_calibration`, default
  `DATA_DIR/camera_calibration.json`, written by `sim.robot.camera.CameraCalibration.save` after
  `sim.robot.perception.calibrate_colours`). Without one the rover's camera is not known: the trial
  runs without a particle filter, and an agent Driver on it sees no rays.

Learning colours renders 60 frames (tens of seconds of CPU on a loaded machine), which is why
the server never does it while a trial runs.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from app.backends.render import FRAME_SIZE
from sim.robot.camera import CameraCalibration, FrontCamera
from sim.trial.specs import SIM, BackendSpec

if TYPE_CHECKING:
    from app.settings import Settings

SIM_CALIBRATION = Path(__file__).with_name("sim_camera.json")
COLOUR_MAZES = 3  # bundled mazes whose renders teach the colours


class CameraUnknown(LookupError):
    """No calibration for this trial's Driver camera; the message says which file is missing."""


def sim_camera() -> FrontCamera:
    w, h = FRAME_SIZE
    return FrontCamera(width=w, height=h, k1=0.0, k2=0.0, noise_std=0.0, supersample=1)


def learned(camera: FrontCamera, seed: int = 1, progress: bool = False) -> CameraCalibration:
    """`camera`'s exact geometry with colours learned from its frames on bundled mazes."""
    from sim.core.navgraph import NavGraph
    from sim.robot.perception import simulated_calibration
    from sim.tasks.library import MazeLibrary

    library = MazeLibrary()
    mazes = [(m, NavGraph.build(m)) for m in (library.load(n) for n in library.names()[:COLOUR_MAZES])]
    return simulated_calibration(camera, mazes, seed=seed, progress=progress)


def driver_calibration(backend: str, settings: Settings) -> CameraCalibration:
    """The calibration of the Driver camera of a trial on `backend` ("sim" or "robot:<id>")."""
    if BackendSpec.parse(backend) == SIM:
        return CameraCalibration.load(SIM_CALIBRATION)
    path = settings.camera_calibration
    if path is None or not Path(path).exists():
        raise CameraUnknown(f"no front-camera calibration at {path} (setting camera_calibration)")
    return CameraCalibration.load(path)


if __name__ == "__main__":
    print(learned(sim_camera(), progress=True).save(SIM_CALIBRATION))

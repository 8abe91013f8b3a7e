"""The Driver camera of a trial's robot seat, as perception needs it (`CameraCalibration`).

- `sim`: the simulator backend's frames are the ideal first-person render (`FRAME_SIZE`, no
  lens distortion, no noise), so its geometry is exact and its colours are learned once from
  renders of the bundled mazes.
- a rover: the lab's calibration file (setting `camera_calibration`, default
  `DATA_DIR/camera_calibration.json`, written by `sim.camera.CameraCalibration.save`); without
  one, the software rover's camera (`sim.camera.FrontCamera()`), learned the same way.

Learning colours renders 60 frames (about ten seconds on an idle core), so learned calibrations
are kept in the cache directory and reused.
"""

from __future__ import annotations

import hashlib
import json
import logging
from pathlib import Path

from sim.camera import CalibrationError, CameraCalibration, FrontCamera

logger = logging.getLogger(__name__)

SIM_CAMERA_SIZE = (320, 240)  # app.backends.sim.FRAME_SIZE, without importing the backend
COLOUR_MAZES = 3  # bundled mazes whose renders teach the colours


def sim_camera() -> FrontCamera:
    w, h = SIM_CAMERA_SIZE
    return FrontCamera(width=w, height=h, k1=0.0, k2=0.0, noise_std=0.0, supersample=1)


def learned(camera: FrontCamera, cache_dir: Path) -> CameraCalibration:
    """`camera`'s geometry with colours learned on bundled mazes, cached by the camera's model."""
    from sim.library import MazeLibrary
    from sim.navgraph import NavGraph
    from sim.perception import simulated_calibration

    key = json.dumps([camera.width, camera.height, camera.k1, camera.k2, camera.gain,
                      camera.noise_std, camera.supersample, COLOUR_MAZES])
    path = Path(cache_dir) / "perception" / f"camera-{hashlib.sha1(key.encode()).hexdigest()[:12]}.json"
    if path.exists():
        try:
            return CameraCalibration.load(path)
        except CalibrationError:
            logger.warning("%s: unreadable cached calibration, learning it again", path)
    library = MazeLibrary()
    mazes = [(m, NavGraph.build(m)) for m in (library.load(n) for n in library.names()[:COLOUR_MAZES])]
    calibration = simulated_calibration(camera, mazes)
    calibration.save(path)
    return calibration


def driver_calibration(backend: str, settings) -> CameraCalibration:
    """The calibration of the Driver camera of a trial on `backend` ("sim" or "robot:<id>")."""
    if backend == "sim":
        return learned(sim_camera(), settings.cache_dir)
    path = settings.camera_calibration
    if path is not None and Path(path).exists():
        return CameraCalibration.load(path)
    return learned(FrontCamera(), settings.cache_dir)

"""`TrialTracker`: a trial's overhead frames -> `pose` events with source "tracker".

One `sim.robot.tracking.OverheadTracker` per trial, calibrated from the `overhead_calibration`
setting's file when there is one, else by the first frame showing the four corner markers.
Frames are tracked off the event loop, one at a time: a frame arriving while the previous one
is still being tracked is skipped (the pose stream runs at the overhead frame rate the machine
can keep). A frame with no rover marker in view gives no pose, never a wrong one.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Callable
from pathlib import Path

from sim.robot.calibration import CalibrationError
from sim.robot.frames import FrameError
from sim.robot.tracking import OverheadCalibration, OverheadTracker, TrackedPose

logger = logging.getLogger(__name__)

FRESH_S = 5.0  # a tracked pose older than this is not where the rover is now (tracking lags under load)


class TrialTracker:
    def __init__(
        self,
        calibration_path: Path | None,
        clock_ns: Callable[[], int],
        record_pose: Callable[[tuple[float, float, float]], None],
    ) -> None:
        """`clock_ns()` is the server clock; each tracked pose goes to `record_pose((x, y, heading))`."""
        calibration = None
        if calibration_path is not None and Path(calibration_path).exists():
            try:
                calibration = OverheadCalibration.load(calibration_path)
            except CalibrationError as err:
                logger.warning("overhead calibration not used, self-calibrating: %s", err)
        self.tracker = OverheadTracker(calibration)
        self.clock_ns, self.record_pose = clock_ns, record_pose
        self.latest: TrackedPose | None = None
        self._busy = False
        self._last_t_ns = 0

    def offer(self, jpeg: bytes, capture_ns: int) -> asyncio.Task[None] | None:
        """Track this frame unless one is being tracked; returns the task doing it."""
        if self._busy or capture_ns <= self._last_t_ns:
            return None
        self._busy = True
        return asyncio.get_running_loop().create_task(self._track(jpeg, capture_ns))

    async def _track(self, jpeg: bytes, capture_ns: int) -> None:
        try:
            pose = await asyncio.to_thread(self.tracker.update, jpeg, capture_ns)
        except (FrameError, CalibrationError, ValueError) as err:
            logger.warning("overhead frame not tracked: %s", err)
            return
        finally:
            self._busy = False
            self._last_t_ns = max(self._last_t_ns, capture_ns)
        self.latest = pose  # None: the last frame tracked did not show the rover
        if pose is not None:
            self.record_pose((pose.x, pose.y, pose.heading))

    async def sighting_after(self, t_ns: int, timeout_s: float) -> TrackedPose | None:
        """The first pose tracked in a frame taken at or after `t_ns` (server clock), waiting up to
        `timeout_s`; None when no frame since showed the rover in time."""
        deadline = self.clock_ns() + timeout_s * 1e9
        while self.clock_ns() < deadline:
            p = self.latest
            if p is not None and p.t_ns >= t_ns:
                return p
            await asyncio.sleep(0.05)
        return None

    def pose(self) -> tuple[float, float, float] | None:
        """The pose in the last frame tracked, while it is fresh; None when that frame did not show
        the rover."""
        p = self.latest
        if p is None or self.clock_ns() - p.t_ns > FRESH_S * 1e9:
            return None
        return p.x, p.y, p.heading

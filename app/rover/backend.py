"""`RemoteRobotBackend`: the real rover in the robot seat, through its websocket (docs/protocol.md).

The robot joins the trial as the `robot` seat: a trial waits for it to start, losing it pauses
the trial and its return resumes it."""

from __future__ import annotations

import math
from collections.abc import AsyncIterator, Callable
from pathlib import Path

from app.backends.base import BackendUnavailable, Frame, MoveOutcome
from app.rover.links import RobotLink, RobotLinks
from app.rover.tracker_seat import TrialTracker
from app.trial.messages import Message
from app.trial.port import RobotTrial
from sim.core.geometry import GRID_STEP_M
from sim.trial.vocabulary import PARTICIPANTS, FrameSource, Move, Outcome, PoseSource, Role

FRAME_AFTER_MOVE_S = 1.0  # how long execute() waits for a frame showing the move's result
# A forward move the overhead camera saw go less than this share of a step ran into something: the
# rover cannot sense a collision itself, so the tracker tells the Driver it bumped, as the
# simulator does. Without a fresh sighting before and after, the move counts as made.
BUMP_SHARE = 0.4


class RobotSeat:
    """The rover as a seat of the trial: its presence pauses and resumes the trial; it hears nothing."""

    role = Role.ROBOT

    def deliver(self, message: Message) -> None:
        pass


class RemoteRobotBackend:
    pose_source = PoseSource.TRACKER

    def __init__(
        self,
        robot_id: int,
        name: str,
        links: RobotLinks,
        trial: RobotTrial,
        overhead_calibration: Path | None,
        clock_ns: Callable[[], int],
    ) -> None:
        self.robot_id, self.name = robot_id, name
        self.links, self.trial = links, trial
        self.tracker = TrialTracker(overhead_calibration, clock_ns, self._tracked)
        self._seat: RobotSeat | None = None
        self._moving = False
        self._closed = False

    async def connect(self) -> None:
        """Follow the robot's link. The rover is a seat the trial needs: until it joins, the trial
        stays `waiting` (`TrialState.waiting_for`), and a running trial it left stays paused
        (the trial's reopening recorded its absence)."""
        self.links.backends.setdefault(self.robot_id, set()).add(self)
        link = self.links.links.get(self.robot_id)
        if link is not None:
            self.link_up(link)

    def link_up(self, link: RobotLink) -> None:
        self._seat = RobotSeat()
        self.trial.join(self._seat)

    def link_down(self, link: RobotLink) -> None:
        if self._seat is not None:
            seat, self._seat = self._seat, None
            self.trial.leave(seat)

    async def execute(self, action: Move) -> MoveOutcome:
        link = self.links.links.get(self.robot_id)
        if link is None:
            raise BackendUnavailable(f"robot {self.name!r} is not connected")
        before = self.tracker.latest if self.tracker.pose() is not None else None
        self._moving = True
        try:
            ack = await link.move(action)
        finally:
            self._moving = False
        if ack.get("status") != "done":
            return MoveOutcome(action, Outcome.REFUSED, f"robot: {ack.get('reason', 'refused')}")
        # The Driver should see where the move left the robot: wait for a frame taken after it.
        finished = ack.get("finished_ns")
        if isinstance(finished, int):
            await self.links.slot(self.robot_id).captured_after(finished, FRAME_AFTER_MOVE_S)
            if action == Move.FORWARD and before is not None:
                after = await self.tracker.sighting_after(finished, FRAME_AFTER_MOVE_S)
                if after is not None:
                    moved = math.hypot(after.x - before.x, after.y - before.y)
                    if moved < BUMP_SHARE * GRID_STEP_M:
                        return MoveOutcome(
                            action,
                            Outcome.COLLISION,
                            f"bumped: the overhead camera saw the rover move {moved * 100:.1f} of "
                            f"{GRID_STEP_M * 100:.0f} cm",
                        )
        return MoveOutcome(action, Outcome.OK)

    @property
    def attended(self) -> bool:
        """Someone is in the trial and it is not paused by a disconnect: only then are frames worth
        recording (a robot may have several trials open, abandoned ones among them; a pause for a
        seat that dropped recorded 139 MB in 6 minutes of waiting)."""
        state = self.trial.state
        waiting = any(reason.startswith("disconnect:") for reason in state.pause_reasons)
        return not waiting and any(role in state.connected for role in PARTICIPANTS)

    async def frames(self) -> AsyncIterator[Frame]:
        slot = self.links.slot(self.robot_id)
        frame = slot.frame
        while (frame := await slot.newer_than(frame, lambda: self._closed)) is not None:
            if self.attended:
                yield frame

    def pose(self) -> tuple[float, float, float] | None:
        """Where the overhead camera's tracker last saw the rover (None without a fresh sighting)."""
        return self.tracker.pose()

    def record_overhead(self, frame: Frame) -> None:
        if self.attended and not self.trial.state.over:
            self.trial.record_frame(frame.jpeg, frame.capture_ns, frame.width, frame.height, FrameSource.OVERHEAD)
            self.tracker.offer(frame.jpeg, frame.capture_ns)

    def _tracked(self, pose: tuple[float, float, float]) -> None:
        if not self._closed and not self.trial.state.over:
            self.trial.record_pose(pose)

    def record_bad_message(self, role: Role, error: str) -> None:
        if not self.trial.state.over:
            self.trial.report_bad_message(role, error)

    async def close(self) -> None:
        self._closed = True
        self.links.backends.get(self.robot_id, set()).discard(self)
        link = self.links.links.get(self.robot_id)
        if link is not None and self._moving:  # only this trial's own move: another may be running
            link.stop()
        await self.links.slot(self.robot_id).wake()

"""`SimulatorBackend`: the replay simulator in the robot seat.

Moves go through the graph's `sim.core.moves.Moves`, the simulator's one stepper (0.07 m
forward, 45 degree turns, a collision leaves the robot where it was); after each move the
first-person render of the new pose is the camera frame, drawn by the server's `FrameRenderer`
(`app.backends.render`: in processes of their own by default). Poses are discrete (a graph node and one of eight headings), so
the JPEG of each pose is kept (the last `FRAMES_KEPT` of this trial): a turn back, or a step back
to where the robot was, costs no render; and the ray observation a frame carries is the maze's
`RayTable` row for the pose (the maze's rays are cast once, not at every frame). The first frame
is drawn beside the trial's opening (`connect` does not wait for it): a crowd of trials opening
at once does not hold its seats' welcomes on every maze's first frame; the first move waits for it.
"""

from __future__ import annotations

import asyncio
import logging
from collections import OrderedDict
from collections.abc import AsyncIterator

from app.backends.base import Frame, MoveOutcome
from app.backends.render import FRAME_SIZE, FrameRenderer, InThread, render_jpeg
from app.clock import ServerClock
from sim.core.dynamics import Action, Pose, continuous_pose
from sim.core.maze import Maze
from sim.core.navgraph import NavGraph
from sim.core.observations import RayTable
from sim.core.rays import RayObservation
from sim.trial.vocabulary import Move, Outcome, PoseSource

logger = logging.getLogger(__name__)
FRAMES_KEPT = 32  # JPEGs of recent poses per trial (about 15 kB each)


class SimulatorBackend:
    pose_source = PoseSource.SIM

    def __init__(
        self,
        maze: Maze,
        graph: NavGraph,
        rays: RayTable,
        start: Pose,
        clock: ServerClock,
        renderer: FrameRenderer | None = None,
    ) -> None:
        self.maze, self.rays, self.clock = maze, rays, clock
        # Only the moves (compiled once per graph, shared by its trials): the graph's all-pairs
        # tables are let go once the trial has its start.
        self.moves = graph.moves
        self.renderer = renderer or InThread()
        self._pose = start
        self._frames: asyncio.Queue[Frame | None] = asyncio.Queue()
        self._jpegs: OrderedDict[Pose, bytes] = OrderedDict()  # recent poses', oldest first
        self._first: asyncio.Task[None] | None = None  # the first frame, while it is drawn

    @property
    def grid_pose(self) -> Pose:
        return self._pose

    async def connect(self) -> None:
        self._first = asyncio.get_running_loop().create_task(self._capture())

    async def execute(self, action: Move) -> MoveOutcome:
        if self._first is not None:  # its frame comes before this move's
            first, self._first = self._first, None
            try:
                await first
            except Exception:  # this move's frame shows where the robot is all the same
                logger.exception("the first simulator frame failed")
        self._pose, collided = self.moves.step(self._pose, Action.of(action))
        await self._capture()
        return MoveOutcome(action, Outcome.COLLISION if collided else Outcome.OK)

    async def frames(self) -> AsyncIterator[Frame]:
        while (frame := await self._frames.get()) is not None:
            yield frame

    def pose(self) -> tuple[float, float, float]:
        return continuous_pose(self.moves, self._pose)

    async def close(self) -> None:
        if self._first is not None:
            self._first.cancel()
        self._frames.put_nowait(None)

    async def _capture(self) -> None:
        pose = self._pose
        jpeg = self._jpegs.pop(pose, None)
        if jpeg is None:  # drawn off the event loop: other trials keep moving
            jpeg = await self.renderer.jpeg(self.maze, *continuous_pose(self.moves, pose))
        self._jpegs[pose] = jpeg
        while len(self._jpegs) > FRAMES_KEPT:
            self._jpegs.popitem(last=False)
        frame = Frame(jpeg, self.clock.now_ns(), *FRAME_SIZE, observation=self.rays.observation(*pose))
        self._frames.put_nowait(frame)

    def frame_at(self, pose: Pose) -> tuple[bytes, RayObservation]:
        """The frame at `pose`, drawn here, and its observation."""
        return render_jpeg(self.maze, *continuous_pose(self.moves, pose)), self.rays.observation(*pose)

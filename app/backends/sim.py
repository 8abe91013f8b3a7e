"""`SimulatorBackend`: the replay simulator in the robot seat.

Moves follow the grid dynamics of `sim.dynamics` (0.07 m forward, 45 degree turns, a
collision leaves the robot where it was); after each move the first-person render of the
new pose is the camera frame. Poses are discrete (a graph node and one of eight headings), so
the JPEG of each pose is kept (the last `FRAMES_KEPT` of this trial): a turn back, or a step back
to where the robot was, costs no render; and the ray observation a frame carries is the maze's
`RayTable` row for the pose (the maze's rays are cast once, not at every frame).
"""

from __future__ import annotations

import asyncio
from collections import OrderedDict
from collections.abc import AsyncIterator

import cv2
import numpy as np

from app.backends.base import Frame, MoveOutcome
from app.clock import ServerClock
from app.trial.vocabulary import MoveAction, Outcome
from sim.dynamics import Action, Pose, step
from sim.geometry import heading_angle
from sim.maze import Maze
from sim.navgraph import NavGraph
from sim.observations import RayTable
from sim.perception import RayObservation

FRAME_SIZE = (320, 240)
JPEG_QUALITY = 80
FRAMES_KEPT = 32  # JPEGs of recent poses per trial (about 15 kB each)


class SimulatorBackend:
    def __init__(self, maze: Maze, graph: NavGraph, rays: RayTable, start: Pose, clock: ServerClock) -> None:
        self.maze, self.graph, self.rays, self.clock = maze, graph, rays, clock
        self._pose = start
        self._frames: asyncio.Queue[Frame | None] = asyncio.Queue()
        self._jpegs: OrderedDict[Pose, tuple[bytes, RayObservation]] = OrderedDict()  # recent poses', oldest first

    @property
    def grid_pose(self) -> Pose:
        return self._pose

    async def connect(self) -> None:
        await self._capture()

    async def execute(self, action: MoveAction) -> MoveOutcome:
        self._pose, collided = step(self.graph, self._pose, Action.parse(action))
        await self._capture()
        return MoveOutcome(action, Outcome.COLLISION if collided else Outcome.OK)

    async def frames(self) -> AsyncIterator[Frame]:
        while (frame := await self._frames.get()) is not None:
            yield frame

    def pose(self) -> tuple[float, float, float]:
        x, y = self.graph.nodes[self._pose.node]
        return float(x), float(y), float(heading_angle(self._pose.heading))

    async def close(self) -> None:
        self._frames.put_nowait(None)

    async def _capture(self) -> None:
        pose = self._pose
        kept = self._jpegs.pop(pose, None)
        if kept is None:
            # Rendering and encoding release the GIL: off the event loop, other trials keep moving.
            kept = await asyncio.to_thread(self.frame_at, pose)
        self._jpegs[pose] = kept
        while len(self._jpegs) > FRAMES_KEPT:
            self._jpegs.popitem(last=False)
        jpeg, observation = kept
        self._frames.put_nowait(Frame(jpeg, self.clock.now_ns(), *FRAME_SIZE, observation=observation))

    def frame_at(self, pose: Pose) -> tuple[bytes, RayObservation]:
        """The frame at `pose` and the simulator's ray observation there (what the frame shows)."""
        x, y = self.graph.nodes[pose.node]
        at = (pose.node, pose.heading)
        rays = self.rays
        observation = RayObservation(
            rays.labels[at],
            rays.depth[at],
            rays.too_close[at],
            np.ones(rays.labels.shape[-1], dtype=bool),
            bool(rays.forward_blocked[at]),
        )
        return render_jpeg(self.maze, float(x), float(y), float(heading_angle(pose.heading))), observation


def render_jpeg(maze: Maze, x: float, y: float, theta: float) -> bytes:
    from sim.render import first_person  # written alongside; imported when the first frame is taken

    image = first_person(maze, x, y, theta, size=FRAME_SIZE)
    ok, buffer = cv2.imencode(".jpg", np.ascontiguousarray(image), [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    if not ok:
        raise RuntimeError("JPEG encoding of a simulator frame failed")
    return buffer.tobytes()

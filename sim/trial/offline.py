"""`OfflineTrial`: a trial refereed in this process, without a server: the same rules (`decide`),
the same events and fold, with the simulator in the robot seat as its backend on the platform
runs it (moves stepped on the robot's graph, one frame per move, its rays the maze's ray table
row) but no image drawn and no clock: each event is stamped one nanosecond after the one before.
Its log is what a recorded trial's would be, and is measured the same way.

The seats take their places once the trial is set up, as agents joining a trial do: they hear where
it stands (its phase, the Driver its frame) and every event from then on. A benchmark's leg begins
navigating (`navigating`): the robot marked where it truly is, as a Commander would have."""

from __future__ import annotations

import math

from sim.core.dynamics import Action, Pose, continuous_pose
from sim.core.navgraph import NavGraph
from sim.core.observations import RayTable
from sim.trial import events as ev
from sim.trial.commands import Act, Command, FinishMove, Join, Judge, Localize, Note, Now
from sim.trial.decide import decide
from sim.trial.events import LoggedEvent
from sim.trial.state import TrialState
from sim.trial.table import Table
from sim.trial.vocabulary import Outcome, PoseSource, Role

FRAME_SIZE = (320, 240)  # the simulator backend's frames (none is drawn here)


class OfflineTrial:
    """One trial from `start` to `targets` (name, (x, y)) in order, agents at `table`."""

    def __init__(
        self,
        maze: str,
        targets: list[tuple[str, tuple[float, float]]],
        start: Pose,
        graph: NavGraph,
        rays: RayTable,
        table: Table,
        navigating: bool = False,
    ) -> None:
        self.graph, self.rays, self.table, self.targets = graph, rays, table, dict(targets)
        self.state = TrialState()
        self.log: list[LoggedEvent] = []
        self.pose = start
        self._seated = False  # the table hears the events once the seats have taken their places
        self._record(
            ev.TrialCreated(
                maze=maze,
                targets=[name for name, _ in targets],
                backend="sim",
                driver="agent",
                commander="agent",
                start=continuous_pose(graph, start),
            )
        )
        self._sample()
        for role in (Role.DRIVER, Role.COMMANDER):
            self.apply(Join(role))
        if navigating:
            x, y, heading = continuous_pose(graph, start)
            self.apply(Act(Role.COMMANDER, Localize(x, y, heading)))
        table.reset()
        self._seated = True
        table.see(
            ev.PhaseChanged(phase=self.state.phase, target_index=self.state.target_index), self._now(), self.state
        )

    def apply(self, command: Command) -> None:
        for event in decide(self.state, command):
            self._record(event)

    async def act(self, act: Act) -> list[ev.Event]:
        now = Now(t_ns=self._now(), within_m=self._within_m() if isinstance(act.action, Judge) else None)
        events = decide(self.state, Act(act.role, act.action, now))
        for event in events:
            if not isinstance(event, ev.MovesRefused):  # a run of refusals is logged by the server's clock
                self._record(event)
            if isinstance(event, ev.MoveRequested):
                self.pose, collided = self.graph.moves.step(self.pose, Action.of(event.action))
                self.apply(FinishMove(event.move_id, Outcome.COLLISION if collided else Outcome.OK))
                self._sample()
        return events

    async def idle(self) -> bool:
        return False  # nothing comes here but what the seats do

    def _sample(self) -> None:
        """Where a move (or the start) left the robot: its pose, then its camera's frame."""
        x, y, heading = continuous_pose(self.graph, self.pose)
        self.apply(Note(ev.PoseSampled(x=x, y=y, heading=heading, source=PoseSource.SIM)))
        frame_id = self.state.last_seq + 1
        n, h = self.pose
        rays = self.rays.observation(n, h)
        frame = ev.FrameRecorded(
            frame_id=frame_id, path="", capture_ns=self._now(), width=FRAME_SIZE[0], height=FRAME_SIZE[1], rays=rays
        )
        self.apply(Note(frame))

    def _within_m(self) -> float | None:
        claim = self.state.pending_claim
        if claim is None:
            return None
        x, y, _ = continuous_pose(self.graph, self.pose)
        ox, oy = self.targets[claim.target]
        return math.hypot(x - ox, y - oy)

    def _now(self) -> int:
        return (self.state.last_t_ns or 0) + 1

    def _record(self, event: ev.Event) -> None:
        t_ns = self._now()
        logged = LoggedEvent(self.state.last_seq + 1, event.kind, t_ns, event.payload())
        self.state.apply_event(event, logged.seq, t_ns)
        self.log.append(logged)
        if self._seated or isinstance(event, ev.FrameRecorded):  # the Driver's page shows the frame it joins to
            self.table.see(event, t_ns, self.state)

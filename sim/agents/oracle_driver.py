"""A Driver that cheats, for measuring Commanders: handed its true pose and the map's views, it
answers every question from all four sides of where it stands without turning to look, and
otherwise carries instructions out as the dialog Driver does. It sees what no Driver sees: it
never ranks with agents."""

from __future__ import annotations

from sim.agents.dialog_driver import DialogDriver, Task, _Task
from sim.core.dynamics import Pose
from sim.core.geometry import HEADINGS
from sim.core.observations import RayTable
from sim.language import instructions as ins
from sim.language.driver_phrasing import Answered, Described
from sim.language.vocab import SIDE_STEPS, Side
from sim.trial.commands import RequestMove, Say


class OracleDriver(DialogDriver):
    """The Driver's seat agent for benches; `pose` is set by the harness before each percept."""

    def __init__(self, rays: RayTable, seed: int = 0) -> None:
        self.rays = rays
        self.pose = Pose(0, 0)
        super().__init__(seed)

    def _look(self, task: _Task) -> RequestMove | Say:
        ask = task.question
        assert ask is not None and task.kind == Task.LOOK  # look tasks are made from questions
        views = {
            side: self.rays.observation(*Pose(self.pose.node, (self.pose.heading + SIDE_STEPS[side]) % HEADINGS))
            for side in Side
        }
        if ask.question == ins.AskedAbout.IS_THERE and ask.label is not None:
            side = ask.side or Side.AHEAD
            return self._say(Answered(ask.label, side, views[side]))
        if ask.question == ins.AskedAbout.SIDE and ask.side is not None:
            return self._say(Described({ask.side: views[ask.side]}, look_around=False))
        return self._say(Described(views, look_around=ask.look_around))

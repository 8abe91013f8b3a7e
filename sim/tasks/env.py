"""The Gymnasium environment `RobotSlang/NDH-v0`: one Driver episode, a view of one episode of
the simulator core (`sim.core.stepper.BatchStepper`).

    import gymnasium, sim.tasks.env                      # importing sim.tasks.env registers the id
    env = gymnasium.make("RobotSlang/NDH-v0", benchmark="../shared/robotslang", split="val_seen")
    obs, info = env.reset(seed=0)                  # or options={"inst_idx": 12}
    obs, reward, terminated, truncated, info = env.step(0)   # forward, left, right, stop
    vec = gymnasium.make_vec("RobotSlang/NDH-v0", num_envs=1000, vectorization_mode="vector_entry_point")

(`gymnasium.make("sim.tasks.env:RobotSlang/NDH-v0", ...)` imports the module itself; `make_vec` with
`vector_entry_point` returns `sim.tasks.batch_env.BatchNavEnv`, the same core over a whole batch.)

Episodes come from a benchmark split (NDH instances, from the episode or recorded start), or
without the benchmark from mazes: the bundled generated mazes by default (so
`gymnasium.make("RobotSlang/NDH-v0")` runs on a fresh machine), or `mazes=` names from the
`MazeLibrary` or `Maze` objects; each episode a random target object and a random start pose
from which it can be reached (options "maze" and "target" choose them).

- actions: Discrete(4), `sim.core.dynamics.Action` (FORWARD, LEFT, RIGHT, STOP).
- observation: a Dict of `rays` (the `OBS_FEATURES` ray features of the pose, float32: label
  one-hot per ray, depths, too-close flags, forward blocked), `target` (Discrete(3): jar, mug,
  paddle), `dialog` (Text: the dialog history as one string, each message after its speaker's
  tag `<COM>` or `<DRI>`; empty for maze episodes) and `action_mask` (MultiBinary(4): forward
  only where it would not collide; turns and stop always).
- reward: metres of topological distance gained toward the goal by the action, plus
  `SUCCESS_REWARD` for a stop within the success radius.
- terminated on stop; truncated after `MAX_EPISODE_ACTIONS` (120) moves (forward, left, right).
- info: `collided`, `steps` (moves made), and on reset `target`, `maze`, `inst_idx` (benchmark
  episodes). What an agent must not learn from (`td`, metres to the goal, `goal` node, `pose`)
  is there only with `privileged_info=True`, for evaluation code.
- `render()` (render_mode "rgb_array"): the Driver's first-person camera as RGB, or the
  top-down map with path and rays when made with `render_view="top_down"`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NotRequired, SupportsInt, TypedDict, Unpack, cast

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from sim.core.dynamics import Action, Pose
from sim.core.geometry import HEADINGS, SUCCESS_RADIUS_M, TABLE_HEIGHT_M, TABLE_WIDTH_M, heading_angle
from sim.core.labels import OBJECTS
from sim.core.maze import Maze
from sim.core.navgraph import MODES, NavGraph
from sim.core.observations import OBS_FEATURES
from sim.core.stepper import _FORWARD, _STOP, MAX_EPISODE_ACTIONS, BatchStepper
from sim.core.world import World, goal_rows
from sim.tasks.benchmark import START_MODES, Benchmark, NDHInstance, goal_node
from sim.tasks.library import MazeLibrary

ENV_ID = "RobotSlang/NDH-v0"
SUCCESS_REWARD = 1.0
RENDER_VIEWS = ("first_person", "top_down")
# No ray is longer than the table's diagonal; one-hot and flags are within [0, 1].
MAX_DEPTH_M = float(math.hypot(TABLE_WIDTH_M, TABLE_HEIGHT_M))
DIALOG_CHARSET = "".join(chr(c) for c in range(32, 127))  # printable ASCII: every benchmark dialog
MAX_DIALOG_CHARS = 4096  # the longest benchmark history is about 2,100; longer ones keep their end
SPEAKER_TAG = {"oracle": "<COM>", "commander": "<COM>", "navigator": "<DRI>", "driver": "<DRI>"}


def observation_space() -> spaces.Dict:
    """The observation of one episode (see the module docstring)."""
    return spaces.Dict(
        {
            "rays": spaces.Box(0.0, MAX_DEPTH_M, (OBS_FEATURES,), np.float32),
            "target": spaces.Discrete(len(OBJECTS)),
            "dialog": spaces.Text(MAX_DIALOG_CHARS, min_length=0, charset=DIALOG_CHARSET),
            "action_mask": spaces.MultiBinary(len(Action)),
        }
    )


def dialog_text(dialog: Sequence[tuple[str, str]]) -> str:
    """The history as one string with speaker tags, within the Text space's charset and length."""
    text = " ".join(f"{SPEAKER_TAG.get(role, '<' + role.upper() + '>')} {message}" for role, message in dialog)
    text = "".join(c if c in DIALOG_CHARSET else "?" for c in text.replace("\n", " "))
    return text[-MAX_DIALOG_CHARS:]


class EpisodeOptions(TypedDict, total=False):
    """`reset(options=...)`: a benchmark episode by `inst_idx`, or a maze episode's maze and target
    (Gymnasium passes them as a plain dict)."""

    inst_idx: int
    maze: str
    target: str


class Observation(TypedDict):
    rays: np.ndarray  # (OBS_FEATURES,) float32
    target: int  # index into OBJECTS
    dialog: str
    action_mask: np.ndarray  # (4,) int8


class StepInfo(TypedDict):
    collided: bool
    steps: int
    td: NotRequired[float]  # with privileged_info only: metres to the goal
    pose: NotRequired[Pose]  # with privileged_info only


class ResetInfo(StepInfo):
    target: str
    maze: str
    inst_idx: int | None
    goal: NotRequired[int]  # with privileged_info only: the goal's node


@dataclass(frozen=True)
class Episode:
    maze: str
    start: Pose
    goal: int  # node of the maze's graph
    target: str
    dialog: str
    inst_idx: int | None


class SourceOptions(TypedDict, total=False):
    """An environment's keyword arguments that say where its episodes come from (`EpisodeSource`)."""

    benchmark: str | Path | Benchmark | None
    split: str
    start: str
    edges: str
    mazes: Sequence[str | Maze] | None
    cache_dir: str | Path | None


class EpisodeSource:
    """Where episodes come from: a benchmark split's NDH instances, or mazes with random starts
    and targets; with each maze's graph, built on first use."""

    def __init__(
        self,
        benchmark: str | Path | Benchmark | None = None,
        split: str = "val_seen",
        start: str = "episode",
        edges: str = "benchmark",
        mazes: Sequence[str | Maze] | None = None,
        cache_dir: str | Path | None = None,
    ):
        if start not in START_MODES:
            raise ValueError(f"start={start!r}: expected one of {', '.join(START_MODES)}")
        if edges not in MODES:
            raise ValueError(f"edges={edges!r}: expected one of {', '.join(MODES)}")
        if benchmark is not None and mazes is not None:
            raise ValueError(
                "give either benchmark= (NDH episodes of a split) or mazes= "
                "(maze names or Maze objects, random start and target), not both"
            )
        self.start_mode, self.edges, self.cache_dir = start, edges, cache_dir
        self._graphs: dict[str, NavGraph] = {}
        self._worlds: dict[tuple[str, ...], World] = {}
        if benchmark is not None:
            self.benchmark: Benchmark | None = (
                benchmark if isinstance(benchmark, Benchmark) else Benchmark(benchmark, cache_dir)
            )
            self.split: str | None = split
            self.instances = self.benchmark.split(split)
            if not self.instances:
                raise ValueError(f"split {split!r} of {self.benchmark.root} has no instances")
            self._by_inst_idx = {inst.inst_idx: k for k, inst in enumerate(self.instances)}
            self._episodes: dict[int, Episode] = {}
            self.names = sorted({inst.run for inst in self.instances}, key=lambda r: (len(r), r))
        else:
            self.benchmark, self.split, self.instances = None, None, []
            self._library = MazeLibrary()
            items: list[str | Maze] = list(self._library.names() if mazes is None else mazes)
            if not items:
                raise ValueError("no mazes: give at least one maze name or Maze in mazes=")
            # Mazes given by name are read on first use; an unknown name fails here.
            self._mazes: dict[str, Maze | None] = {}
            for item in items:
                if isinstance(item, Maze):
                    self._mazes[item.name] = item
                else:
                    self._library.path(item)
                    self._mazes[item] = None
            self.names = list(self._mazes)

    def maze(self, name: str) -> Maze:
        if self.benchmark is not None:
            return self.benchmark.maze(name)
        maze = self._mazes[name]
        if maze is None:
            maze = self._mazes[name] = self._library.load(name)
        return maze

    def graph(self, name: str) -> NavGraph:
        if name not in self._graphs:
            self._graphs[name] = (
                self.benchmark.graph(name, self.edges)
                if self.benchmark is not None
                else NavGraph.build(self.maze(name), self.edges, cache_dir=self.cache_dir)
            )
        return self._graphs[name]

    def world(self, names: Sequence[str] | None = None) -> World:
        """The mazes `names` (default: all) compiled with float32 observations, once."""
        names = tuple(self.names if names is None else names)
        if names not in self._worlds:
            self._worlds[names] = World.compile(
                [(n, self.maze(n), self.graph(n)) for n in names], cache_dir=self.cache_dir
            )
        return self._worlds[names]

    def sample(self, rng: np.random.Generator, options: EpisodeOptions) -> Episode:
        return self._ndh_episode(rng, options) if self.benchmark is not None else self._random_episode(rng, options)

    def _ndh_episode(self, rng: np.random.Generator, options: EpisodeOptions) -> Episode:
        if "inst_idx" in options:
            k = self._by_inst_idx.get(int(options["inst_idx"]))
            if k is None:
                raise ValueError(f"options['inst_idx']={options['inst_idx']}: no such instance in split {self.split!r}")
        else:
            k = int(rng.integers(len(self.instances)))
        if k not in self._episodes:
            inst: NDHInstance = self.instances[k]
            graph = self.graph(inst.run)
            self._episodes[k] = Episode(
                inst.run,
                START_MODES[self.start_mode](graph, inst),
                goal_node(graph, inst),
                inst.target,
                dialog_text(inst.dialog),
                inst.inst_idx,
            )
        return self._episodes[k]

    def _random_episode(self, rng: np.random.Generator, options: EpisodeOptions) -> Episode:
        name = options.get("maze")
        if name is None:
            name = self.names[int(rng.integers(len(self.names)))]
        elif name not in self._mazes:
            raise ValueError(f"options['maze']={name!r}: not one of this environment's mazes ({', '.join(self.names)})")
        maze, graph = self.maze(name), self.graph(name)
        target = options.get("target") or sorted(maze.objects)[int(rng.integers(3))]
        if target not in maze.objects:
            raise ValueError(f"options['target']={target!r}: expected one of jar, mug, paddle")
        goal = graph.nearest_node(*maze.objects[target])
        # Start anywhere the goal can be reached from, outside the success radius.
        to_goal = graph.dist[:, goal]
        candidates = np.flatnonzero(np.isfinite(to_goal) & (to_goal > SUCCESS_RADIUS_M))
        if candidates.size == 0:
            candidates = np.flatnonzero(np.isfinite(to_goal))
        node = int(candidates[rng.integers(candidates.size)])
        heading = int(rng.integers(HEADINGS))
        return Episode(name, Pose(node, heading), goal, target, "", None)


def start_episodes(
    stepper: BatchStepper, source: EpisodeSource, envs: Sequence[int] | np.ndarray, episodes: Sequence[Episode]
) -> None:
    """Start `episodes` in positions `envs` of `stepper` (its world holds their mazes)."""
    world = stepper.world
    for env, ep in zip(envs, episodes):  # per episode: its goal rows come from its own graph
        off = int(world.offset[world.index(ep.maze)])
        dist, hop = goal_rows(source.graph(ep.maze), [ep.goal])
        stepper.start([env], [off + ep.start.node], [ep.start.heading], [off + ep.goal], dist, hop)


class NDHEnv(gym.Env):
    """Navigation from dialog history, as a Gymnasium environment (see the module docstring)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 5}

    def __init__(
        self,
        render_mode: str | None = None,
        render_view: str = "first_person",
        max_actions: int = MAX_EPISODE_ACTIONS,
        privileged_info: bool = False,
        **source: Unpack[SourceOptions],
    ):
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(f"render_mode={render_mode!r}: expected None or 'rgb_array'")
        if render_view not in RENDER_VIEWS:
            raise ValueError(f"render_view={render_view!r}: expected one of {', '.join(RENDER_VIEWS)}")
        if max_actions < 1:
            raise ValueError(f"max_actions={max_actions}: must be at least 1")
        self.source = EpisodeSource(**source)
        self.render_mode, self.render_view = render_mode, render_view
        self.max_actions, self.privileged_info = max_actions, privileged_info
        self.action_space = spaces.Discrete(len(Action))
        self.observation_space = observation_space()
        self._steppers: dict[str, BatchStepper] = {}  # one maze's world each, made on first use
        self._episode: Episode | None = None
        self._stepper: BatchStepper | None = None

    # -- the Gymnasium interface ----------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Observation, dict[str, Any]]:
        super().reset(seed=seed)
        episode = self.source.sample(self.np_random, cast(EpisodeOptions, options or {}))
        if episode.maze not in self._steppers:
            self._steppers[episode.maze] = BatchStepper(
                self.source.world([episode.maze]), 1, self.max_actions, record=True
            )
        self._episode, self._stepper = episode, self._steppers[episode.maze]
        start_episodes(self._stepper, self.source, [0], [episode])
        info: ResetInfo = {
            "collided": False,
            "steps": 0,
            "target": episode.target,
            "maze": episode.maze,
            "inst_idx": episode.inst_idx,
        }
        if self.privileged_info:
            info["td"], info["pose"], info["goal"] = float(self._stepper.td[0]), episode.start, episode.goal
        return self._observation(), dict(info)  # Gymnasium's info is a plain dict

    def step(self, action: SupportsInt) -> tuple[Observation, float, bool, bool, dict[str, Any]]:
        stepper = self._stepper
        if stepper is None or stepper.done[0]:
            raise RuntimeError("step() after the episode ended: call reset() first")
        a = int(action)
        if not 0 <= a <= _STOP:
            raise ValueError(f"action {action!r}: expected 0 forward, 1 left, 2 right or 3 stop")
        before = float(stepper.td[0])
        collided = bool(stepper.step(np.array([a]))[0])
        td = float(stepper.td[0])
        reward = before - td if td != math.inf else 0.0
        terminated = bool(stepper.stopped[0])
        if terminated and td <= SUCCESS_RADIUS_M:
            reward += SUCCESS_REWARD
        truncated = bool(stepper.done[0]) and not terminated
        info: StepInfo = {"collided": collided, "steps": int(stepper.steps[0])}
        if self.privileged_info:
            info["td"], info["pose"] = td, self.pose
        return self._observation(), reward, terminated, truncated, dict(info)

    def _observation(self) -> Observation:
        stepper, episode = self._stepper, self._episode
        assert stepper is not None and episode is not None, "reset() starts an episode first"
        mask = np.ones(_STOP + 1, dtype=np.int8)
        mask[_FORWARD] = not stepper.forward_blocked()[0]
        return {
            "rays": stepper.observations()[0],
            "target": OBJECTS.index(episode.target),
            "dialog": episode.dialog,
            "action_mask": mask,
        }

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gym.logger.warn("render() without render_mode: make the environment with render_mode='rgb_array'")
            return None
        if self._episode is None:
            raise RuntimeError("render() before reset()")
        from sim.robot import render  # the camera's scene is built on first use

        maze, graph, pose = self.source.maze(self._episode.maze), self.episode_graph, self.pose
        x, y = graph.nodes[pose.node]
        theta = float(heading_angle(pose.heading))
        if self.render_view == "first_person":
            bgr = render.first_person(maze, float(x), float(y), theta)
        else:
            from sim.core.observations import RayTable

            rays = RayTable.build(maze, graph, cache_dir=self.source.cache_dir)
            bgr = render.top_down(
                maze,
                pose=(x, y, theta),
                path=graph.nodes[self.path],
                rays=(rays.labels[pose.node, pose.heading], rays.depth[pose.node, pose.heading]),
            )
        return np.ascontiguousarray(bgr[..., ::-1])

    # -- read-only views for callers and tests ------------------------------------------
    @property
    def pose(self) -> Pose:
        """The pose in the episode's maze graph (its world holds that maze alone)."""
        if self._stepper is None:
            raise RuntimeError("no episode yet: call reset() first")
        return Pose(int(self._stepper.node[0]), int(self._stepper.heading[0]))

    @property
    def episode_graph(self) -> NavGraph:
        if self._episode is None:
            raise RuntimeError("no episode yet: call reset() first")
        return self.source.graph(self._episode.maze)

    @property
    def path(self) -> list[int]:
        """Nodes visited this episode, the start first (a collision repeats the node)."""
        if self._stepper is None:
            return []
        return self._stepper.trajectories()[0]


if ENV_ID not in gym.registry:
    gym.register(id=ENV_ID, entry_point="sim.tasks.env:NDHEnv", vector_entry_point="sim.tasks.batch_env:BatchNavEnv")

"""The Gymnasium environment `RobotSlang/NDH-v0`: one Driver episode in the replay simulator.

    import gymnasium, sim.env                      # importing sim.env registers the id
    env = gymnasium.make("RobotSlang/NDH-v0", benchmark="../shared/robotslang", split="val_seen")
    obs, info = env.reset(seed=0)                  # or options={"inst_idx": 12}
    obs, reward, terminated, truncated, info = env.step(0)   # forward, left, right, stop

(`gymnasium.make("sim.env:RobotSlang/NDH-v0", ...)` imports the module itself.)

Episodes come from a benchmark split (NDH instances, from the episode or recorded start), or
without the benchmark from mazes: the bundled generated mazes by default (so
`gymnasium.make("RobotSlang/NDH-v0")` runs on a fresh machine), or `mazes=` names from the
`MazeLibrary` or `Maze` objects; each episode a random target object and a random start pose
from which it can be reached (options "maze" and "target" choose them).

- actions: Discrete(4), `sim.dynamics.Action` (FORWARD, LEFT, RIGHT, STOP).
- observation: the ray features of the pose, `RayTable.features()` (`OBS_FEATURES` float32:
  label one-hot per ray, depths, too-close flags, forward blocked).
- reward: metres of topological distance gained toward the goal by the action, plus
  `SUCCESS_REWARD` for a stop within the success radius.
- terminated on stop; truncated after `MAX_EPISODE_ACTIONS` (120) moves (forward, left, right).
- info: `td` (metres to the goal on the graph), `collided`, `pose` (`Pose`), `steps` (moves
  made), and on reset `goal` (node), `target`, `maze`, `inst_idx` (benchmark episodes).
- `render()` (render_mode "rgb_array"): the Driver's first-person camera as RGB, or the
  top-down map with path and rays when made with `render_view="top_down"`.

Everything static is looked up from tables built once per maze, so a step is a few list and
array reads.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from sim.benchmark import MAX_EPISODE_ACTIONS, START_MODES, Benchmark, goal_node
from sim.dynamics import Action, Pose
from sim.geometry import HEADINGS, SUCCESS_RADIUS_M, TABLE_HEIGHT_M, TABLE_WIDTH_M, heading_angle
from sim.library import MazeLibrary
from sim.maze import Maze
from sim.navgraph import MODES, NavGraph
from sim.observations import OBS_FEATURES, RayTable

ENV_ID = "RobotSlang/NDH-v0"
SUCCESS_REWARD = 1.0
RENDER_VIEWS = ("first_person", "top_down")
# No ray is longer than the table's diagonal; one-hot and flags are within [0, 1].
MAX_DEPTH_M = float(math.hypot(TABLE_WIDTH_M, TABLE_HEIGHT_M))


@dataclass(frozen=True, eq=False)
class World:
    """One maze with its graph and observation tables, in the forms a step reads fastest."""

    maze: Maze
    graph: NavGraph
    rays: RayTable
    features: np.ndarray  # (N * 8, OBS_FEATURES) float32, row node * 8 + heading
    forward: list  # forward[node][heading] -> node, -1 = collision

    @classmethod
    def build(cls, maze: Maze, graph: NavGraph, cache_dir: str | Path | None = None) -> "World":
        rays = RayTable.build(maze, graph, cache_dir=cache_dir)
        features = rays.features().reshape(graph.n * HEADINGS, OBS_FEATURES)
        return cls(maze=maze, graph=graph, rays=rays, features=features,
                   forward=graph.forward.tolist())


@dataclass(frozen=True)
class _Episode:
    world: World
    start: Pose
    goal: int
    target: str
    inst_idx: int | None


class NDHEnv(gym.Env):
    """Navigation from dialog history, as a Gymnasium environment (see the module docstring)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 5}

    def __init__(self, benchmark: str | Path | Benchmark | None = None, split: str = "val_seen",
                 start: str = "episode", edges: str = "benchmark",
                 mazes: Sequence[str | Maze] | None = None, render_mode: str | None = None,
                 render_view: str = "first_person", max_actions: int = MAX_EPISODE_ACTIONS,
                 cache_dir: str | Path | None = None):
        if start not in START_MODES:
            raise ValueError(f"start={start!r}: expected one of {', '.join(START_MODES)}")
        if edges not in MODES:
            raise ValueError(f"edges={edges!r}: expected one of {', '.join(MODES)}")
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(f"render_mode={render_mode!r}: expected None or 'rgb_array'")
        if render_view not in RENDER_VIEWS:
            raise ValueError(f"render_view={render_view!r}: expected one of {', '.join(RENDER_VIEWS)}")
        if max_actions < 1:
            raise ValueError(f"max_actions={max_actions}: must be at least 1")
        if benchmark is not None and mazes is not None:
            raise ValueError("give either benchmark= (NDH episodes of a split) or mazes= "
                             "(maze names or Maze objects, random start and target), not both")
        self.render_mode, self.render_view = render_mode, render_view
        self.start_mode, self.edges, self.max_actions = start, edges, max_actions
        self.cache_dir = cache_dir
        self.action_space = spaces.Discrete(len(Action))
        self.observation_space = spaces.Box(0.0, MAX_DEPTH_M, (OBS_FEATURES,), np.float32)

        self._worlds: dict[str, World] = {}
        if benchmark is not None:
            self.benchmark = benchmark if isinstance(benchmark, Benchmark) else Benchmark(benchmark, cache_dir)
            self.split = split
            self.instances = self.benchmark.split(split)
            if not self.instances:
                raise ValueError(f"split {split!r} of {self.benchmark.root} has no instances")
            self._by_inst_idx = {inst.inst_idx: k for k, inst in enumerate(self.instances)}
            self._episodes: dict[int, _Episode] = {}
            self.maze_names = sorted({inst.run for inst in self.instances})
        else:
            self.benchmark, self.split, self.instances = None, None, []
            self._library = MazeLibrary()
            items = self._library.names() if mazes is None else list(mazes)
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
            self.maze_names = list(self._mazes)

        self._episode: _Episode | None = None
        self._node = self._heading = self._steps = 0
        self._to_goal: list[float] = []
        self._done = True
        self._path: list[int] = []

    # -- worlds and episodes ------------------------------------------------------
    def world(self, name: str) -> World:
        """The maze `name` with its graph and tables, built on first use."""
        if name not in self._worlds:
            if self.benchmark is not None:
                maze, graph = self.benchmark.maze(name), self.benchmark.graph(name, self.edges)
            else:
                maze = self._mazes[name] or self._library.load(name)
                graph = NavGraph.build(maze, self.edges, cache_dir=self.cache_dir)
            self._worlds[name] = World.build(maze, graph, self.cache_dir)
        return self._worlds[name]

    def _ndh_episode(self, options: dict) -> _Episode:
        if "inst_idx" in options:
            k = self._by_inst_idx.get(int(options["inst_idx"]))
            if k is None:
                raise ValueError(f"options['inst_idx']={options['inst_idx']}: no such instance "
                                 f"in split {self.split!r}")
        else:
            k = int(self.np_random.integers(len(self.instances)))
        if k not in self._episodes:
            inst = self.instances[k]
            world = self.world(inst.run)
            self._episodes[k] = _Episode(world, START_MODES[self.start_mode](world.graph, inst),
                                         goal_node(world.graph, inst), inst.target, inst.inst_idx)
        return self._episodes[k]

    def _random_episode(self, options: dict) -> _Episode:
        name = options.get("maze")
        if name is None:
            name = self.maze_names[int(self.np_random.integers(len(self.maze_names)))]
        elif name not in self._mazes:
            raise ValueError(f"options['maze']={name!r}: not one of this environment's mazes "
                             f"({', '.join(self.maze_names)})")
        world = self.world(name)
        target = options.get("target") or sorted(world.maze.objects)[int(self.np_random.integers(3))]
        if target not in world.maze.objects:
            raise ValueError(f"options['target']={target!r}: expected one of jar, mug, paddle")
        goal = world.graph.nearest_node(*world.maze.objects[target])
        # Start anywhere the goal can be reached from, outside the success radius.
        to_goal = world.graph.dist[:, goal]
        candidates = np.flatnonzero(np.isfinite(to_goal) & (to_goal > SUCCESS_RADIUS_M))
        if candidates.size == 0:
            candidates = np.flatnonzero(np.isfinite(to_goal))
        node = int(candidates[self.np_random.integers(candidates.size)])
        heading = int(self.np_random.integers(HEADINGS))
        return _Episode(world, Pose(node, heading), goal, target, None)

    # -- the Gymnasium interface ----------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        options = options or {}
        episode = self._ndh_episode(options) if self.benchmark is not None else self._random_episode(options)
        self._episode = episode
        self._node, self._heading = episode.start.node, episode.start.heading
        self._steps, self._done = 0, False
        self._to_goal = episode.world.graph.dist[:, episode.goal].tolist()
        self._forward, self._features = episode.world.forward, episode.world.features
        self._path = [self._node]
        info = {"td": self._to_goal[self._node], "collided": False, "pose": episode.start,
                "steps": 0, "goal": episode.goal, "target": episode.target,
                "maze": episode.world.maze.name, "inst_idx": episode.inst_idx}
        return self._features[self._node * HEADINGS + self._heading].copy(), info

    def step(self, action):
        if self._done:
            raise RuntimeError("step() after the episode ended: call reset() first")
        a = int(action)
        node, heading = self._node, self._heading
        collided = terminated = False
        if a == 0:
            nxt = self._forward[node][heading]
            if nxt < 0:
                collided = True
            else:
                self._node = node = nxt
        elif a == 1:
            self._heading = heading = (heading + 1) & 7
        elif a == 2:
            self._heading = heading = (heading - 1) & 7
        elif a == 3:
            terminated = True
        else:
            raise ValueError(f"action {action!r}: expected 0 forward, 1 left, 2 right or 3 stop")

        before, td = self._to_goal[self._path[-1]], self._to_goal[node]
        reward = before - td if td != math.inf else 0.0
        if terminated:
            if td <= SUCCESS_RADIUS_M:
                reward += SUCCESS_REWARD
        else:
            self._steps += 1
            self._path.append(node)
        truncated = not terminated and self._steps >= self.max_actions
        self._done = terminated or truncated
        info = {"td": td, "collided": collided, "pose": Pose(node, heading), "steps": self._steps}
        return self._features[node * HEADINGS + heading].copy(), reward, terminated, truncated, info

    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() without render_mode: make the environment with render_mode='rgb_array'")
            return None
        if self._episode is None:
            raise RuntimeError("render() before reset()")
        from sim import render  # the camera's scene is built on first use

        world = self._episode.world
        x, y = world.graph.nodes[self._node]
        theta = float(heading_angle(self._heading))
        if self.render_view == "first_person":
            bgr = render.first_person(world.maze, float(x), float(y), theta)
        else:
            rays = (world.rays.labels[self._node, self._heading], world.rays.depth[self._node, self._heading])
            bgr = render.top_down(world.maze, pose=(x, y, theta), path=world.graph.nodes[self._path], rays=rays)
        return np.ascontiguousarray(bgr[..., ::-1])

    # -- read-only views for callers and tests ------------------------------------------
    @property
    def pose(self) -> Pose:
        return Pose(self._node, self._heading)

    @property
    def episode_world(self) -> World:
        if self._episode is None:
            raise RuntimeError("no episode yet: call reset() first")
        return self._episode.world

    @property
    def path(self) -> list[int]:
        """Nodes visited this episode, the start first (a collision repeats the node)."""
        return list(self._path)


if ENV_ID not in gym.registry:
    gym.register(id=ENV_ID, entry_point="sim.env:NDHEnv")

"""`Seq2SeqDriver`: a trained NDH Driver in the web UI's Driver seat.

It acts like the NDH agent at test time: the dialog so far (and the current target) is the
instruction; each time the dialog grows or the target changes it is re-encoded and the decoder
starts afresh from where the robot is, as an NDH episode starts from the dialog history. Its
observation is the 13-ray table of the simulator at the robot's pose. On a backend without a
known pose (a rover) it observes the rays perceived from the camera frame (`rays`, in
`RayTable.features` layout) and masks forward where the particle filter's belief, once it is
concentrated, stands facing a wall on the graph (else where the perceived rays say the way
ahead is blocked); with neither it sees zeros and forward is not masked. After the Commander
rejects a claim it does not stop again until it has moved. Where the pose is known (the
simulator, or a rover's concentrated belief) it counts the poses of its episode, for its
revisit penalty, as the rollout does.

The web app seats it as `agent:seq2seq` (`app/drivers/seq2seq.py`), with the checkpoint of the
setting ROBOTSLANG_SEQ2SEQ_CHECKPOINT.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import torch

from models.agent import START, STOP, greedy_actions, observation_input
from sim.core.dynamics import Action, Pose, snap_pose, step
from sim.core.labels import object_label
from sim.core.maze import Maze
from sim.core.navgraph import NavGraph
from sim.core.observations import RayTable

MazeLoader = Callable[[str], tuple[Maze, NavGraph]]
MOVES = (Action.FORWARD, Action.LEFT, Action.RIGHT)  # the order of `greedy_actions`' visits
BELIEF_MASK_SPREAD_M = 0.15  # a belief spread wider than this says too little about the walls ahead


class Seq2SeqDriver:
    def __init__(self, checkpoint: str | Path, load_maze: MazeLoader):
        from models.train import load_agent

        self.agent, self.tokenizer, ckpt = load_agent(checkpoint)
        self.blind = ckpt["train_config"]["blind"]
        self.load_maze = load_maze
        self.graph: NavGraph | None = None
        self.rays: np.ndarray | None = None

    def reset(self, info: dict[str, Any]) -> None:
        maze, self.graph = self.load_maze(info["maze"])
        self.rays = RayTable.build(maze, self.graph).features()
        self.encoded_for: tuple | None = None
        self._rejected = 0
        self._stop_held = False

    @torch.no_grad()
    def _encode(self, dialog: list[dict[str, str]], target: str) -> None:
        ids = self.tokenizer.encode([(turn["role"], turn["text"]) for turn in dialog], target)
        tokens = torch.tensor([ids], dtype=torch.long)
        lengths = torch.tensor([0 if self.blind == "language" else len(ids)])
        self.ctx, self.ctx_mask, self.state = self.agent.encode(tokens, lengths)
        self.prev = torch.tensor([START])
        self.encoded_for = (len(dialog), target)
        self._visits: Counter[Pose] = Counter()  # a new episode: poses counted afresh, as in training

    @torch.no_grad()
    def act(self, dialog: list[dict[str, str]], observation: dict[str, Any]) -> str:
        graph, table = self.graph, self.rays
        if graph is None or table is None:
            raise RuntimeError("Seq2SeqDriver.act before reset(info)")
        target = observation["target"]
        if self.encoded_for != (len(dialog), target):
            self._encode(dialog, target)
        if observation.get("rejected", 0) > self._rejected:
            self._rejected = observation["rejected"]
            self._stop_held = True  # the Commander said no: move before claiming again
        pose = observation.get("pose")
        here = snap_pose(graph, *pose) if pose is not None else self._believed_pose(graph, observation.get("belief"))
        visits = None
        if here is not None:
            self._visits[here] += 1
            visits = torch.tensor([[self._visits[step(graph, here, a)[0]] for a in MOVES]], dtype=torch.float32)
        if here is not None and self.blind != "vision":
            obs = torch.from_numpy(table[here.node, here.heading][None].copy())
            blocked = torch.tensor([bool(graph.forward[here.node, here.heading] < 0)])
        elif observation.get("rays") is not None and self.blind != "vision":
            rays = np.asarray(observation["rays"], dtype=np.float32)
            obs = torch.from_numpy(rays[None].copy())
            blocked = torch.tensor([self._blocked(graph, rays, observation.get("belief"))])
        else:
            obs = torch.zeros(1, table.shape[2])
            blocked = torch.tensor([False])
        stop_allowed = torch.tensor([not self._stop_held])
        label = -1 if self.blind == "language" else int(object_label(target))
        obs = observation_input(self.agent.config, obs, torch.tensor([label]))
        logits, self.state, _, _, stop = self.agent.step(
            obs, self.prev, self.state, self.ctx, self.ctx_mask, blocked, stop_allowed
        )
        action = int(greedy_actions(logits, stop, stop_allowed, visits, self.agent.config.revisit_penalty)[0])
        self.prev = torch.tensor([action])
        if action != STOP:
            self._stop_held = False
        return Action(action).word

    def _blocked(self, graph: NavGraph, rays: np.ndarray, belief: dict[str, float] | None) -> bool:
        """Forward masked on a rover: from the belief where it is concentrated, else the camera."""
        p = self._believed_pose(graph, belief)
        if p is not None:
            return bool(graph.forward[p.node, p.heading] < 0)
        return bool(rays[-1] > 0.5)  # the perceived forward-blocked flag

    @staticmethod
    def _believed_pose(graph: NavGraph, belief: dict[str, float] | None) -> Pose | None:
        """A rover's pose on the graph, where the particle filter's belief is concentrated."""
        if belief is None or belief["spread_m"] > BELIEF_MASK_SPREAD_M:
            return None
        return snap_pose(graph, belief["x"], belief["y"], belief["heading"])

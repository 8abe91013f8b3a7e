"""`Seq2SeqDriver`: a trained NDH Driver in the web UI's Driver seat (`agent:seq2seq`).

It acts like the NDH agent at test time, on what a human Driver gets (`sim.agents.turns`): the
dialog so far is the instruction; each time the dialog grows or the target changes it is
re-encoded and the decoder starts afresh from where the robot is, as an NDH episode starts from
the dialog history. It holds still until the Commander has marked it on the map, then decides
one move on each frame after its move (`StepwiseDriver`). It observes the rays of its frame (the
simulator's, or those perceived from a rover's pixels; zeros where unreadable) and forward is
masked where they say the way ahead is blocked. The target's name is the object the Commander
named last for this target (the Driver's page shows only its number); until then the target
flags are off, as in the language-blind ablation. After the Commander rejects a claim it does
not stop again until it has moved. For its revisit penalty it counts poses by its own
odometry on the grid of moves (a collision leaves it where it was), never by the true pose.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import torch

from models.agent import START, STOP, greedy_actions, observation_input
from sim.agents.stepwise import StepwiseDriver
from sim.core.dynamics import Action
from sim.core.geometry import HEADING_DI, HEADING_DJ, HEADINGS
from sim.core.labels import object_label
from sim.core.observations import OBS_FEATURES
from sim.robot.perception import features
from sim.trial.vocabulary import Move, Outcome

Odometry = tuple[int, int, int]  # grid steps (i, j) from the start, heading index
MOVES = (Move.FORWARD, Move.LEFT, Move.RIGHT)  # the order of `greedy_actions`' visits


def odometry_step(pose: Odometry, move: Move) -> Odometry:
    """Where a move leads on the grid of moves (left turns by +45 degrees, as `sim.core.dynamics`)."""
    i, j, h = pose
    if move == Move.FORWARD:
        return i + int(HEADING_DI[h]), j + int(HEADING_DJ[h]), h
    return i, j, (h + (1 if move == Move.LEFT else -1)) % HEADINGS


class Seq2SeqDriver(StepwiseDriver):
    def __init__(self, checkpoint: str | Path):
        from models.train import load_agent

        self.agent, self.tokenizer, ckpt = load_agent(checkpoint)
        self.blind = ckpt["train_config"]["blind"]
        self.encoded_for: tuple | None = None
        self._here: Odometry = (0, 0, 0)
        self._visits: Counter[Odometry] = Counter()
        self._stop_held = False

    def on_target(self) -> None:
        self.encoded_for = None
        self._stop_held = False

    def on_moved(self, move: Move, result: Outcome) -> None:
        if result == Outcome.OK:
            self._here = odometry_step(self._here, move)
        self._stop_held = False

    def on_rejected(self) -> None:
        self._stop_held = True  # the Commander said no: move before claiming again

    @torch.no_grad()
    def _encode(self, target: str) -> None:
        ids = self.tokenizer.encode([(str(role), text) for role, text in self.dialog], target)
        tokens = torch.tensor([ids], dtype=torch.long)
        lengths = torch.tensor([0 if self.blind == "language" else len(ids)])
        self.ctx, self.ctx_mask, self.state = self.agent.encode(tokens, lengths)
        self.prev = torch.tensor([START])
        self.encoded_for = (len(self.dialog), target)
        # A new episode: poses counted afresh, as in training, from here.
        self._here, self._visits = (0, 0, 0), Counter()

    @torch.no_grad()
    def decide(self) -> Move | None:
        target = self.named or ""
        if self.encoded_for != (len(self.dialog), target):
            self._encode(target)
        self._visits[self._here] += 1
        visits = torch.tensor([[self._visits[odometry_step(self._here, m)] for m in MOVES]], dtype=torch.float32)
        rays = self.rays
        if rays is not None and rays.problem is None and self.blind != "vision":
            obs = torch.from_numpy(features(rays)[None])
            blocked = torch.tensor([bool(rays.forward_blocked)])
        else:
            obs = torch.zeros(1, OBS_FEATURES)
            blocked = torch.tensor([False])
        stop_allowed = torch.tensor([not self._stop_held])
        label = -1 if self.blind == "language" or not target else int(object_label(target))
        obs = observation_input(self.agent.config, obs, torch.tensor([label]))
        logits, self.state, _, _, stop = self.agent.step(
            obs, self.prev, self.state, self.ctx, self.ctx_mask, blocked, stop_allowed
        )
        action = int(greedy_actions(logits, stop, stop_allowed, visits, self.agent.config.revisit_penalty)[0])
        self.prev = torch.tensor([action])
        return None if action == STOP else Move(Action(action).word)

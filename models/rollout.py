"""Batched NDH episodes: the agent acts for a whole batch at once on the compiled `World`.

Feedback decides which action is executed: `teacher` (the shortest-path action), `student`
(sampled from the agent; stop masked until the goal's node), or `argmax` (evaluation).
The loss is cross entropy against the teacher's action at every decision the agent makes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F

from models.agent import FORWARD, LEFT, RIGHT, START, STOP, Seq2SeqAgent
from models.data import EpisodeSet, World, goal_distance, teacher_actions
from sim.geometry import HEADINGS

FEEDBACKS = ("teacher", "student", "argmax")
BLINDS = ("none", "vision", "language")
MAX_ACTIONS = 120


@dataclass
class Rollout:
    nodes: np.ndarray  # (B, T + 1) global node before each action, then the final node
    actions: np.ndarray  # (B, T) actions taken, -1 after the episode ended
    final_node: np.ndarray  # (B,)
    steps: np.ndarray  # (B,) actions taken, stop included
    loss: torch.Tensor | None = None


def run_episodes(agent: Seq2SeqAgent, world: World, episodes: EpisodeSet, idx: np.ndarray,
                 feedback: str, blind: str = "none", max_actions: int = MAX_ACTIONS,
                 generator: torch.Generator | None = None, progress_weight: float = 1.0,
                 train: bool = False) -> Rollout:
    if feedback not in FEEDBACKS:
        raise ValueError(f"unknown feedback {feedback!r}; expected one of {', '.join(FEEDBACKS)}")
    if blind not in BLINDS:
        raise ValueError(f"unknown ablation {blind!r}; expected one of {', '.join(BLINDS)}")
    idx = np.asarray(idx)
    b = len(idx)
    tokens = torch.from_numpy(episodes.tokens[idx])
    lengths = torch.from_numpy(episodes.lengths[idx])
    if blind == "language":
        lengths = torch.zeros_like(lengths)
    ctx, ctx_mask, state = agent.encode(tokens, lengths)

    node = episodes.start_node[idx].copy()
    heading = episodes.start_heading[idx].copy()
    start_dist = np.maximum(goal_distance(world, episodes, idx, node), 1e-6)
    prev = torch.full((b,), START, dtype=torch.long)
    done = np.zeros(b, dtype=bool)
    nodes = np.zeros((b, max_actions + 1), dtype=np.int64)
    actions = np.full((b, max_actions), -1, dtype=np.int64)
    steps = np.zeros(b, dtype=np.int64)
    total_loss, decisions = torch.zeros(()), 0
    for t in range(max_actions):
        nodes[:, t] = node
        if done.all():
            nodes[:, t:] = node[:, None]
            break
        obs = world.observe(node, heading)
        if blind == "vision":
            obs[:] = 0.0
        blocked = world.forward[node, heading] < 0
        stop_allowed = torch.from_numpy(node == episodes.goal_node[idx]) if feedback == "student" else None
        logits, state, progress = agent.step(torch.from_numpy(obs), prev, state, ctx, ctx_mask,
                                             torch.from_numpy(blocked), stop_allowed)
        teacher = teacher_actions(world, episodes, idx, node, heading)
        active = torch.from_numpy(~done)
        if train:
            target = torch.from_numpy(teacher)
            total_loss = total_loss + F.cross_entropy(logits[active], target[active], reduction="sum")
            if progress is not None:
                done_frac = 1.0 - goal_distance(world, episodes, idx, node) / start_dist
                goal = torch.from_numpy(np.clip(done_frac, 0.0, 1.0)).float()
                total_loss = total_loss + progress_weight * F.mse_loss(
                    progress[active], goal[active], reduction="sum")
            decisions += int(active.sum())
        if feedback == "teacher":
            chosen = teacher
        elif feedback == "student":
            chosen = torch.multinomial(torch.softmax(logits.detach(), dim=1), 1, generator=generator)[:, 0].numpy()
        else:
            chosen = logits.detach().argmax(dim=1).numpy()
        chosen = np.where(done, STOP, chosen)
        actions[~done, t] = chosen[~done]
        steps += ~done
        moving = (chosen == FORWARD) & ~blocked
        node = np.where(moving, world.forward[node, heading], node)
        heading = (heading + (chosen == LEFT) - (chosen == RIGHT)) % HEADINGS
        done |= chosen == STOP
        prev = torch.from_numpy(chosen)
    else:
        nodes[:, max_actions] = node
    loss = total_loss / max(decisions, 1) if train else None
    return Rollout(nodes=nodes, actions=actions, final_node=node, steps=steps, loss=loss)

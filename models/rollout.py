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

from models.agent import FORWARD, LEFT, RIGHT, START, STOP, Seq2SeqAgent, observation_input
from models.data import EpisodeSet, World, goal_distance, teacher_actions
from sim.benchmark import MAX_EPISODE_ACTIONS
from sim.geometry import HEADINGS

FEEDBACKS = ("teacher", "student", "argmax")
BLINDS = ("none", "vision", "language")
MAX_ACTIONS = MAX_EPISODE_ACTIONS  # the benchmark's cap, as for the baselines


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
    # The target word is part of the language: the language-blind agent does not know it.
    target_label = torch.from_numpy(episodes.target_label[idx] if blind != "language" else np.full(b, -1))
    step_logits, step_targets, step_active, step_progress, step_goal = [], [], [], [], []
    for t in range(max_actions):
        nodes[:, t] = node
        if done.all():
            nodes[:, t:] = node[:, None]
            break
        obs = world.observe(node, heading)
        if blind == "vision":
            obs[:] = 0.0
        blocked = world.forward[node, heading] < 0
        teacher = teacher_actions(world, episodes, idx, node, heading)
        # Student forcing may stop only where the teacher would: at the goal's node (or, on a
        # node cut off from it, nowhere else to go).
        stop_allowed = torch.from_numpy(teacher == STOP) if feedback == "student" else None
        obs_in = observation_input(agent.config, torch.from_numpy(obs), target_label)
        logits, state, progress = agent.step(obs_in, prev, state, ctx, ctx_mask, torch.from_numpy(blocked),
                                             stop_allowed)
        active = torch.from_numpy(~done)
        if train:  # the loss is computed once over all steps, below
            step_logits.append(logits)
            step_targets.append(torch.from_numpy(teacher))
            step_active.append(active)
            if progress is not None:
                done_frac = 1.0 - goal_distance(world, episodes, idx, node) / start_dist
                step_progress.append(progress)
                step_goal.append(torch.from_numpy(np.clip(done_frac, 0.0, 1.0)).float())
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
    loss = None
    if train:
        active = torch.stack(step_active).float()
        ce = F.cross_entropy(torch.stack(step_logits).flatten(0, 1), torch.stack(step_targets).flatten(),
                             reduction="none")
        total = (ce * active.flatten()).sum()
        if step_progress:
            err = (torch.stack(step_progress) - torch.stack(step_goal)) ** 2
            total = total + progress_weight * (err * active).sum()
        loss = total / active.sum().clamp(min=1.0)
    return Rollout(nodes=nodes, actions=actions, final_node=node, steps=steps, loss=loss)

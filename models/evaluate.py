"""Scoring a trained Driver on a split with the benchmark's metrics (sim.core.metrics).

The agent acts greedily (argmax, forward masked where it would collide) from the episode start
pose, at most 120 actions; each trajectory is scored by `sim.core.metrics.score_trajectory` on the
maze's benchmark graph, exactly as the baselines are.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from models.agent import STOP, Seq2SeqAgent
from models.data import EpisodeSet, World
from models.rollout import MAX_ACTIONS, run_episodes
from sim.core.geometry import heading_angle
from sim.core.metrics import EpisodeResult, score_trajectory
from sim.tasks.benchmark import Benchmark, NDHInstance

EVAL_BATCH = 100


def agent_name(train_config: dict) -> str:
    """'seq2seq-baseline-student-none': model, feedback and ablation of a checkpoint."""
    return f"seq2seq-{train_config['model']}-{train_config['feedback']}-{train_config['blind']}"


@torch.no_grad()
def evaluate_agent(
    agent: Seq2SeqAgent,
    bench: Benchmark,
    world: World,
    episodes: EpisodeSet,
    blind: str,
    name: str,
    seed: int = 0,
    max_actions: int = MAX_ACTIONS,
) -> list[EpisodeResult]:
    agent.eval()
    results = []
    for lo in range(0, len(episodes), EVAL_BATCH):
        idx = np.arange(lo, min(lo + EVAL_BATCH, len(episodes)))
        roll = run_episodes(agent, world, episodes, idx, "argmax", blind, max_actions)
        for row, k in enumerate(idx):
            inst = episodes.instances[k]
            off = world.offset[episodes.geometry.maze[k]]
            moves = int(((roll.actions[row] >= 0) & (roll.actions[row] != STOP)).sum())
            local = roll.nodes[row, : moves + 1] - off
            graph = bench.graph(inst.run)
            score = score_trajectory(graph, local, int(episodes.geometry.goal_node[k] - off))
            sx, sy = graph.nodes[local[0]]
            start = (float(sx), float(sy), float(heading_angle(int(episodes.geometry.start_heading[k]))))
            results.append(
                EpisodeResult.scored(episodes.split, inst.inst_idx, name, seed, start, inst.target_pose, moves, score)
            )
    return results


def evaluate_checkpoint(
    bench: Benchmark,
    world: World | None,
    checkpoint: str | Path,
    split: str,
    name: str | None = None,
    instances: list[NDHInstance] | None = None,
) -> list[EpisodeResult]:
    """Per-instance results of a checkpoint on `split` (or on `instances` of it), under its own
    tokenizer and ablation; without a `world`, only the mazes of those instances are compiled."""
    from models.train import load_agent

    agent, tokenizer, ckpt = load_agent(checkpoint)
    cfg = ckpt["train_config"]
    instances = bench.split(split) if instances is None else instances
    if world is None:
        world = World.build(bench, sorted({inst.run for inst in instances}), cache_dir=bench.cache_dir)
    episodes = EpisodeSet.build(bench, world, split, tokenizer, instances=instances)
    return evaluate_agent(
        agent,
        bench,
        world,
        episodes,
        cfg["blind"],
        name or agent_name(cfg),
        seed=int(cfg["seed"]),
        max_actions=int(cfg["max_actions"]),
    )

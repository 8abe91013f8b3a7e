"""Run policies over a benchmark split and score them with the NDH metrics."""

from __future__ import annotations

from typing import Callable, Iterable

import numpy as np
from tqdm import tqdm

from sim.baselines import Policy, make_baseline
from sim.benchmark import MAX_EPISODE_ACTIONS, START_MODES, Benchmark, NDHInstance, goal_node
from sim.dynamics import Action, Pose, step
from sim.geometry import heading_angle
from sim.metrics import EpisodeResult, score_trajectory
from sim.navgraph import NavGraph


def run_episode(graph: NavGraph, start: Pose, goal: int, policy: Policy, rng: np.random.Generator,
                max_actions: int = MAX_EPISODE_ACTIONS) -> tuple[list[int], int]:
    """Roll a policy out; returns the nodes visited (start first) and the moves made."""
    policy.reset(graph, start, goal, rng)
    pose, nodes, moves = start, [start.node], 0
    while moves < max_actions:
        action = policy.act(pose)
        if action == Action.STOP:
            break
        pose, _ = step(graph, pose, action)
        nodes.append(pose.node)
        moves += 1
    return nodes, moves


def episode_seed(seed: int, inst_idx: int) -> np.random.Generator:
    """One independent stream per (seed, instance): results do not depend on instance order."""
    return np.random.default_rng([seed, inst_idx])


def evaluate(benchmark: Benchmark, split: str, policies: dict[str, Callable[[], Policy]],
             start: str = "episode", edges: str = "benchmark", seeds: Iterable[int] = (0,),
             instances: list[NDHInstance] | None = None, progress: bool = True) -> list[EpisodeResult]:
    """Every (instance, policy, seed) episode of a split, scored on the `edges` graph."""
    if start not in START_MODES:
        raise ValueError(f"unknown start {start!r}; expected one of {', '.join(START_MODES)}")
    instances = benchmark.split(split) if instances is None else instances
    seeds = list(seeds)
    results = []
    bar = tqdm(instances, desc=f"{split}", unit="inst", disable=not progress)
    for inst in bar:
        graph = benchmark.graph(inst.run, edges)
        start_pose = START_MODES[start](graph, inst)
        goal = goal_node(graph, inst)
        sx, sy = graph.nodes[start_pose.node]
        for name, factory in policies.items():
            for seed in seeds:
                nodes, moves = run_episode(graph, start_pose, goal, factory(), episode_seed(seed, inst.inst_idx))
                score = score_trajectory(graph, nodes, goal)
                results.append(EpisodeResult(
                    split=split, inst_idx=inst.inst_idx, agent=name, seed=seed,
                    start_x=float(sx), start_y=float(sy), start_heading=float(heading_angle(start_pose.heading)),
                    goal_x=float(inst.target_pose[0]), goal_y=float(inst.target_pose[1]),
                    td=score.td, otd=score.otd, steps=moves, success=score.success, spl=score.spl))
    return results


def evaluate_baselines(benchmark: Benchmark, split: str, agents: Iterable[str], **kwargs) -> list[EpisodeResult]:
    policies = {name: (lambda name=name: make_baseline(name)) for name in agents}
    for name in policies:
        make_baseline(name)  # unknown names fail before any work is done
    return evaluate(benchmark, split, policies, **kwargs)

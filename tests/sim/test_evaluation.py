"""The batched baselines give, episode for episode, what the per-episode reference runner gives."""

from __future__ import annotations

from sim.core.geometry import heading_angle
from sim.core.metrics import EpisodeResult, score_trajectory
from sim.tasks.benchmark import Benchmark, episode_start, goal_node
from sim.tasks.evaluation import episode_seed, evaluate_baselines
from tests.sim.reference_baselines import make_baseline, run_episode


def reference(bench, split, instances, agents, seeds):
    rows = []
    for inst in instances:
        graph = bench.graph(inst.run)
        start, goal = episode_start(graph, inst), goal_node(graph, inst)
        sx, sy = graph.nodes[start.node]
        for name in agents:
            for seed in seeds:
                nodes, moves = run_episode(graph, start, goal, make_baseline(name), episode_seed(seed, inst.inst_idx))
                s = score_trajectory(graph, nodes, goal)
                rows.append(
                    EpisodeResult(
                        split,
                        inst.inst_idx,
                        name,
                        seed,
                        float(sx),
                        float(sy),
                        float(heading_angle(start.heading)),
                        inst.target_pose[0],
                        inst.target_pose[1],
                        s.td,
                        s.otd,
                        moves,
                        s.success,
                        s.spl,
                    )
                )
    return rows


def test_batched_baselines_equal_the_reference_runner_episode_for_episode(benchmark_path):
    bench = Benchmark(benchmark_path)
    instances = bench.split("val_seen")[:25]
    agents, seeds = ("stop", "shortest", "random"), (0, 1)
    got = evaluate_baselines(bench, "val_seen", agents, seeds=seeds, instances=instances, progress=False)
    assert got == reference(bench, "val_seen", instances, agents, seeds)
    assert {r.steps for r in got if r.agent == "random"} == {120}

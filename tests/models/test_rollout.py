"""Masking and the teacher in batched episodes on real mazes."""

from __future__ import annotations

import numpy as np
import torch

from models.agent import FORWARD, STOP, AgentConfig, Seq2SeqAgent, mask_logits
from models.data import goal_distance, teacher_actions
from models.rollout import run_episodes
from sim.benchmark import episode_start, goal_node
from sim.dynamics import teacher_actions as sim_teacher_actions


def test_mask_logits_forbids_forward_where_blocked_and_stop_where_not_allowed():
    logits = torch.zeros(3, 4)
    masked = mask_logits(logits, torch.tensor([True, False, True]), torch.tensor([True, False, False]))
    probs = torch.softmax(masked, dim=1)
    assert probs[0, FORWARD] == 0 and probs[2, FORWARD] == 0 and probs[1, FORWARD] > 0
    assert probs[1, STOP] == 0 and probs[2, STOP] == 0 and probs[0, STOP] > 0


def test_batched_teacher_matches_the_simulator_teacher(bench, few):
    world, eps = few["world"], few["train_set"]
    rng = np.random.default_rng(0)
    for k, inst in enumerate(few["train"]):
        graph = bench.graph(inst.run)
        off = world.offset[eps.run[k]]
        nodes = rng.integers(0, graph.n, 200)
        headings = rng.integers(0, 8, 200)
        goal = goal_node(graph, inst)
        expected = sim_teacher_actions(graph, nodes, headings, np.full(200, goal))
        got = teacher_actions(world, eps, np.full(200, k), nodes + off, headings)
        assert (got == expected).all()
        assert eps.start_node[k] - off == episode_start(graph, inst).node


def test_teacher_forcing_reaches_every_goal_and_stops_there(few):
    world, eps = few["world"], few["train_set"]
    agent = Seq2SeqAgent(AgentConfig(vocab_size=len(few["tokenizer"]), obs_features=world.obs_features))
    idx = np.arange(len(eps))
    roll = run_episodes(agent, world, eps, idx, "teacher")
    assert (roll.final_node == eps.goal_node).all()
    assert (goal_distance(world, eps, idx, roll.final_node) == 0).all()


def test_untrained_agents_never_drive_into_walls_and_student_stops_only_at_the_goal(few):
    world, eps = few["world"], few["train_set"]
    torch.manual_seed(0)
    agent = Seq2SeqAgent(AgentConfig(vocab_size=len(few["tokenizer"]), obs_features=world.obs_features))
    idx = np.arange(len(eps))
    for feedback in ("student", "argmax"):
        roll = run_episodes(agent, world, eps, idx, feedback, generator=torch.Generator().manual_seed(1))
        for b in range(len(idx)):
            for t in range(roll.steps[b]):
                if roll.actions[b, t] == FORWARD:
                    # A forward move always changes the node: it was never masked-out (blocked).
                    assert roll.nodes[b, t + 1] != roll.nodes[b, t]
        if feedback == "student":
            stopped = (roll.actions == STOP).any(axis=1)
            assert (roll.final_node[stopped] == eps.goal_node[stopped]).all()


def test_target_flags_are_the_target_column_of_each_rays_one_hot_label(few):
    from models.agent import observation_input
    from sim.labels import Label
    from sim.observations import N_LABELS, N_RAYS

    world = few["world"]
    obs = torch.from_numpy(world.observe(np.arange(50), np.zeros(50, dtype=np.int64)))
    config = AgentConfig(vocab_size=10, obs_features=world.obs_features, target_rays=True)
    flags = observation_input(config, obs, torch.full((50,), int(Label.MUG)))[:, world.obs_features:]
    labels = obs[:, :N_RAYS * N_LABELS].reshape(50, N_RAYS, N_LABELS).argmax(dim=2)
    assert flags.shape == (50, N_RAYS)
    assert torch.equal(flags.bool(), labels == int(Label.MUG))
    unknown = observation_input(config, obs, torch.full((50,), -1))[:, world.obs_features:]
    assert (unknown == 0).all()

"""Masking and the teacher in batched episodes on real mazes."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from models.agent import FORWARD, LEFT, RIGHT, STOP, AgentConfig, Seq2SeqAgent, mask_logits
from models.data import goal_distance
from models.rollout import run_episodes
from sim.core.dynamics import teacher_actions as sim_teacher_actions
from sim.core.geometry import SUCCESS_RADIUS_M
from sim.core.stepper import BatchStepper
from sim.tasks.benchmark import episode_start, goal_node


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
        off = world.offset[eps.geometry.maze[k]]
        nodes = rng.integers(0, graph.n, 200)
        headings = rng.integers(0, 8, 200)
        goal = goal_node(graph, inst)
        expected = sim_teacher_actions(graph, nodes, headings, np.full(200, goal))
        stepper = BatchStepper(world, 200)
        stepper.start(
            np.arange(200),
            nodes + off,
            headings,
            np.full(200, eps.geometry.goal_node[k]),
            eps.geometry.goal_dist[[k] * 200],
            eps.geometry.goal_next[[k] * 200],
        )
        assert (stepper.teacher_actions() == expected).all()
        assert eps.geometry.start_node[k] - off == episode_start(graph, inst).node


def test_teacher_forcing_reaches_every_goal_and_stops_there(few):
    world, eps = few["world"], few["train_set"]
    agent = Seq2SeqAgent(AgentConfig(vocab_size=len(few["tokenizer"]), obs_features=world.obs_features))
    idx = np.arange(len(eps))
    roll = run_episodes(agent, world, eps, idx, "teacher")
    assert (roll.final_node == eps.geometry.goal_node).all()
    assert (goal_distance(world, eps, idx, roll.final_node) == 0).all()


@pytest.mark.slow
def test_an_agent_that_always_wants_forward_never_drives_into_a_wall(few):
    world, eps = few["world"], few["train_set"]
    torch.manual_seed(0)
    agent = Seq2SeqAgent(AgentConfig(vocab_size=len(few["tokenizer"]), obs_features=world.obs_features, dropout=0.0))
    with torch.no_grad():
        agent.policy.bias[FORWARD] = 50.0  # forward whenever it can; a turn (or stop) only where blocked
    idx = np.arange(len(eps))
    for feedback in ("student", "argmax"):
        roll = run_episodes(agent, world, eps, idx, feedback, generator=torch.Generator().manual_seed(1))
        forward = roll.actions[:, :-1] == FORWARD
        moved = roll.nodes[:, 1:-1] != roll.nodes[:, :-2]
        assert forward.sum() >= len(idx) and moved[forward].all()  # every forward it took went somewhere
        if feedback == "student":  # it cannot stop, so at walls it must have turned
            assert ((roll.actions[:, :-1] >= 0) & ~forward).any()


def test_student_forcing_stops_only_at_the_goal_however_much_the_agent_wants_to(few):
    world, eps = few["world"], few["train_set"]
    agent = Seq2SeqAgent(AgentConfig(vocab_size=len(few["tokenizer"]), obs_features=world.obs_features, dropout=0.0))
    with torch.no_grad():
        agent.policy.bias[STOP] = 50.0  # the agent all but always wants to stop
    idx = np.arange(len(eps))
    greedy = run_episodes(agent, world, eps, idx, "argmax")
    assert (greedy.steps == 1).all()  # evaluation lets it stop at once
    roll = run_episodes(agent, world, eps, idx, "student", generator=torch.Generator().manual_seed(1), max_actions=30)
    stopped = (roll.actions == STOP).any(axis=1)
    assert (roll.final_node[stopped] == eps.geometry.goal_node[stopped]).all()
    assert (~stopped).any() and (roll.steps[~stopped] == 30).all()  # elsewhere it had to go on


def test_target_flags_are_the_target_column_of_each_rays_one_hot_label(few):
    from models.agent import observation_input
    from sim.core.labels import Label
    from sim.core.observations import N_LABELS, N_RAYS

    world = few["world"]
    obs = torch.from_numpy(world.obs[np.arange(50) * 8].astype(np.float32))  # heading 0
    config = AgentConfig(vocab_size=10, obs_features=world.obs_features, target_rays=True)
    flags = observation_input(config, obs, torch.full((50,), int(Label.MUG)))[:, world.obs_features :]
    labels = obs[:, : N_RAYS * N_LABELS].reshape(50, N_RAYS, N_LABELS).argmax(dim=2)
    assert flags.shape == (50, N_RAYS)
    assert torch.equal(flags.bool(), labels == int(Label.MUG))
    unknown = observation_input(config, obs, torch.full((50,), -1))[:, world.obs_features :]
    assert (unknown == 0).all()


def test_a_lone_dialog_is_encoded_as_in_a_padded_batch(few):
    eps = few["train_set"]
    agent = Seq2SeqAgent(AgentConfig(vocab_size=len(few["tokenizer"]), obs_features=few["world"].obs_features)).eval()
    tokens, lengths = torch.from_numpy(eps.tokens).clone(), torch.from_numpy(eps.lengths).clone()
    tokens[0, 30:], lengths[0] = 0, 30  # benchmark dialogs fill the 100 tokens: make one short
    _, mask, (h, c) = agent.encode(tokens, lengths)
    assert mask[0].sum() == 30 and mask[1].all()
    _, _, (h1, c1) = agent.encode(tokens[:1, :30], lengths[:1])
    assert torch.allclose(h[0], h1[0], atol=1e-6) and torch.allclose(c[0], c1[0], atol=1e-6)
    assert not torch.allclose(h[0], h[1], atol=1e-3)  # and the short dialog was read as itself


def test_rewards_are_the_metres_covered_in_forward_steps_and_a_bonus_for_stopping_at_the_goal(few):
    from models.rollout import SUCCESS_BONUS, move_rewards
    from sim.core.geometry import GRID_STEP_M

    world, eps = few["world"], few["train_set"]
    idx = np.array([0, 0, 0, 0])
    goal = eps.geometry.goal_node[0]
    off = world.offset[eps.geometry.maze[0]]
    far = off + int(np.argmax(np.where(np.isfinite(eps.geometry.goal_dist[0]), eps.geometry.goal_dist[0], -1)))
    moved = world.forward[far][world.forward[far] >= 0][0]
    before = np.array([far, far, goal, far])
    after = np.array([moved, far, goal, moved])
    chosen = np.array([FORWARD, STOP, STOP, FORWARD])
    done = np.array([False, False, False, True])
    d_before, d_after = goal_distance(world, eps, idx, before), goal_distance(world, eps, idx, after)
    reward = move_rewards(d_before, d_after, chosen, done)
    d = d_before - d_after
    assert reward[0] == pytest.approx(d[0] / GRID_STEP_M, rel=1e-5)
    assert reward[1] == 0 and reward[2] == SUCCESS_BONUS and reward[3] == 0


def test_actor_critic_loss_on_a_hand_computed_episode():
    from models.rollout import ENTROPY_WEIGHT, GAMMA, actor_critic_loss

    # One episode of two steps, rewards 1 then 2, then over; a second step of a finished episode.
    logp = [
        torch.tensor([-0.5], requires_grad=True),
        torch.tensor([-1.0], requires_grad=True),
        torch.tensor([-7.0], requires_grad=True),
    ]
    entropy = [torch.tensor([0.3]), torch.tensor([0.2]), torch.tensor([9.0])]
    value = [
        torch.tensor([1.5], requires_grad=True),
        torch.tensor([1.0], requires_grad=True),
        torch.tensor([4.0], requires_grad=True),
    ]
    reward = [torch.tensor([1.0]), torch.tensor([2.0]), torch.tensor([0.0])]
    active = torch.tensor([[1.0], [1.0], [0.0]])
    loss = actor_critic_loss(logp, entropy, value, reward, active)
    returns = [1 + GAMMA * 2, 2.0]
    advantage = [returns[0] - 1.5, returns[1] - 1.0]
    expected = (
        0.5 * advantage[0]
        + 1.0 * advantage[1]
        + 0.5 * 0.5 * (advantage[0] ** 2 + advantage[1] ** 2)
        - ENTROPY_WEIGHT * 0.5
    )
    assert loss.item() == pytest.approx(expected, rel=1e-6)
    loss.backward()
    assert logp[2].grad.item() == 0 and value[2].grad.item() == 0  # the finished step teaches nothing
    assert logp[0].grad.item() == pytest.approx(-advantage[0])  # the policy is pushed toward what paid


def test_an_agent_with_a_critic_may_stop_anywhere_under_student_forcing(few):
    world, eps = few["world"], few["train_set"]
    torch.manual_seed(0)
    agent = Seq2SeqAgent(
        AgentConfig(vocab_size=len(few["tokenizer"]), obs_features=world.obs_features, critic=True, target_rays=True)
    )
    idx = np.arange(len(eps))
    roll = run_episodes(agent, world, eps, idx, "student", generator=torch.Generator().manual_seed(1), train=True)
    stopped = (roll.actions == STOP).any(axis=1)
    assert (roll.final_node[stopped] != eps.geometry.goal_node[stopped]).any()  # untrained: stops short
    assert torch.isfinite(roll.loss)
    roll.loss.backward()
    assert agent.value.weight.grad.abs().sum() > 0  # the critic learns from the returns


def test_guided_episodes_follow_the_teacher_and_teach_only_the_cross_entropy_and_the_stop_head(few):
    world, eps = few["world"], few["train_set"]
    torch.manual_seed(0)
    config = AgentConfig(
        vocab_size=len(few["tokenizer"]), obs_features=world.obs_features, critic=True, stop_head=True, dropout=0.0
    )
    agent = Seq2SeqAgent(config)
    idx = np.arange(len(eps))
    gen = torch.Generator().manual_seed(1)
    roll = run_episodes(agent, world, eps, idx, "student", generator=gen, train=True, guided_share=0.5)
    teacher = run_episodes(agent, world, eps, idx, "teacher")
    half = len(idx) // 2
    assert (roll.actions[:half] == teacher.actions[:half]).all()  # the first half is guided
    assert (roll.final_node[:half] == eps.geometry.goal_node[:half]).all()
    assert (roll.actions[half:] != teacher.actions[half:]).any()  # the rest is the student's

    all_guided = run_episodes(agent, world, eps, idx, "student", generator=gen, train=True, guided_share=1.0)
    all_guided.loss.backward()
    assert agent.value.weight.grad.abs().sum() == 0  # no return of the student's own to learn from
    assert agent.stop.weight.grad.abs().sum() > 0 and agent.policy.weight.grad.abs().sum() > 0


def test_a_stop_head_decides_the_greedy_stop(few):
    world, eps = few["world"], few["train_set"]
    agent = Seq2SeqAgent(
        AgentConfig(vocab_size=len(few["tokenizer"]), obs_features=world.obs_features, dropout=0.0, stop_head=True)
    )
    idx = np.arange(len(eps))
    with torch.no_grad():
        agent.policy.bias[STOP] = -50.0  # the policy itself never wants to stop
        agent.stop.bias.fill_(50.0)  # the head is sure the goal is here
    assert (run_episodes(agent, world, eps, idx, "argmax").steps == 1).all()
    with torch.no_grad():
        agent.stop.bias.fill_(-50.0)  # and sure it is not
    assert (run_episodes(agent, world, eps, idx, "argmax", max_actions=20).steps == 20).all()


def test_the_stop_head_learns_whether_the_goal_is_within_the_success_radius(few):
    """Its labels, checked against the distances of the teacher's path: a head sure of "near"
    pays the clamped cross entropy at every far step, one sure of "far" at every near step."""
    world, eps = few["world"], few["train_set"]
    agent = Seq2SeqAgent(
        AgentConfig(vocab_size=len(few["tokenizer"]), obs_features=world.obs_features, dropout=0.0, stop_head=True)
    )
    idx = np.arange(len(eps))
    losses = {}
    for bias in (50.0, -50.0):
        with torch.no_grad():
            agent.stop.bias.fill_(bias)
        roll = run_episodes(agent, world, eps, idx, "teacher", train=True)
        losses[bias] = roll.loss.item()
    near = far = 0
    for t in range(roll.nodes.shape[1] - 1):
        decided = roll.steps > t
        td = goal_distance(world, eps, idx, roll.nodes[:, t])
        near += int((decided & (td <= SUCCESS_RADIUS_M)).sum())
        far += int((decided & (td > SUCCESS_RADIUS_M)).sum())
    assert near > 0 and far > near
    sure_far = -np.log(1.0 - np.float32(1 - 1e-6))  # the clamped probabilities, in float32
    sure_near = -np.log(np.float32(1e-6))
    assert losses[50.0] - losses[-50.0] == pytest.approx((sure_far * far - sure_near * near) / (near + far), rel=1e-4)


def test_a_revisit_penalty_takes_a_greedy_agent_that_spins_on_the_spot_somewhere_else(few):
    world, eps = few["world"], few["train_set"]
    idx = np.arange(len(eps))
    distinct = {}
    for penalty in (0.0, 20.0):
        agent = Seq2SeqAgent(
            AgentConfig(
                vocab_size=len(few["tokenizer"]),
                obs_features=world.obs_features,
                dropout=0.0,
                revisit_penalty=penalty,
            )
        )
        with torch.no_grad():
            agent.policy.bias[LEFT] = 10.0  # it wants to turn left, always
            agent.policy.bias[STOP] = -50.0
            roll = run_episodes(agent, world, eps, idx, "argmax", max_actions=30)
        distinct[penalty] = [len(set(roll.nodes[k].tolist())) for k in range(len(idx))]
    assert set(distinct[0.0]) == {1}  # round and round on its start node
    # With the penalty, once round it has been in every pose of its node: it leaves.
    assert min(distinct[20.0]) >= 2


def test_next_slots_are_where_each_move_leads(few):
    world, eps = few["world"], few["train_set"]
    idx = np.arange(len(eps))
    for action in (FORWARD, LEFT, RIGHT):
        stepper = BatchStepper(world, len(idx))
        eps.geometry.start(stepper, idx)
        expected = stepper.next_slots()[:, action]
        stepper.step(np.full(len(idx), action))
        assert (stepper.slot == expected).all()

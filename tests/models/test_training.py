"""A short real training run: the loss falls, checkpoints round-trip, training resumes, and the
evaluation has the shape of `eval baselines`."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
import torch

from models.evaluate import evaluate_checkpoint
from models.rollout import run_episodes
from models.train import TrainConfig, load_agent, train
from sim.core.metrics import CSV_COLUMNS, summarize, write_csv
from sim.tasks.evaluation import evaluate_baselines

# Each test trains an agent: minutes of CPU together (the quick loop is -m "not slow").
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def trained(bench, few, tmp_path_factory):
    out = tmp_path_factory.mktemp("run")
    cfg = TrainConfig(feedback="teacher", iters=12, batch=8, lr=1e-2, eval_every=4, max_actions=40)
    result = train(
        bench, cfg, out, world=few["world"], progress=False, train_instances=few["train"], eval_instances=few["val"]
    )
    return cfg, out, result


def test_loss_falls(trained):
    _, out, result = trained
    losses = [h["loss"] for h in result["history"]]
    assert len(losses) == 3
    assert losses[-1] < 0.7 * losses[0]
    assert json.loads((out / "history.json").read_text()) == result["history"]


def test_checkpoints_round_trip(trained, few):
    _, out, result = trained
    assert result["best"]["val_td"] == min(h["val_td"] for h in result["history"])
    agent, tokenizer, ckpt = load_agent(out / "last.pt")
    assert ckpt["iteration"] == 12 and tokenizer.vocab == few["tokenizer"].vocab
    world, eps = few["world"], few["train_set"]
    idx = np.arange(len(eps))
    again, _, _ = load_agent(out / "last.pt")
    with torch.no_grad():
        a = run_episodes(agent, world, eps, idx, "argmax")
        b = run_episodes(again, world, eps, idx, "argmax")
    assert (a.actions == b.actions).all()
    best, _, best_ckpt = load_agent(out / "best.pt")
    assert best_ckpt["iteration"] == result["best"]["iteration"]


def test_training_resumes_from_last_checkpoint(trained, bench, few):
    cfg, out, _ = trained
    longer = TrainConfig(**{**cfg.__dict__, "iters": 16})
    result = train(
        bench, longer, out, world=few["world"], progress=False, train_instances=few["train"], eval_instances=few["val"]
    )
    assert [h["iteration"] for h in result["history"]] == [4, 8, 12, 16]
    with pytest.raises(ValueError, match="different configuration"):
        train(
            bench,
            TrainConfig(**{**cfg.__dict__, "feedback": "student"}),
            out,
            world=few["world"],
            progress=False,
            train_instances=few["train"],
            eval_instances=few["val"],
        )


def test_improved_variant_plays_with_its_averaged_weights_and_resumes_with_both(bench, few, tmp_path):
    from models.train import MODELS, update_average

    cfg = TrainConfig(feedback="student", model="improved", iters=6, batch=8, eval_every=3, max_actions=40)
    kwargs = dict(world=few["world"], progress=False, train_instances=few["train"], eval_instances=few["val"])
    train(bench, cfg, tmp_path, **kwargs)
    ckpt = torch.load(tmp_path / "last.pt", weights_only=False)
    played, _, _ = load_agent(tmp_path / "last.pt")
    for name, weights in played.state_dict().items():
        assert torch.equal(weights, ckpt["eval_state_dict"][name])
    assert any(not torch.equal(ckpt["state_dict"][k], ckpt["eval_state_dict"][k]) for k in ckpt["state_dict"])
    # Resumed to 9 iterations, the average continues from where it was: its next step mixes in
    # the trained weights with the variant's decay.
    train(bench, TrainConfig(**{**cfg.__dict__, "iters": 9}), tmp_path, **kwargs)
    assert torch.load(tmp_path / "last.pt", weights_only=False)["iteration"] == 9
    decay = MODELS["improved"].weight_average
    averaged, trained_now = load_agent(tmp_path / "last.pt")[0], load_agent(tmp_path / "last.pt")[0]
    trained_now.load_state_dict(torch.load(tmp_path / "last.pt", weights_only=False)["state_dict"])
    before = averaged.policy.weight.clone()
    update_average(averaged, trained_now, decay)
    assert torch.allclose(averaged.policy.weight, decay * before + (1 - decay) * trained_now.policy.weight)


def test_missing_or_foreign_checkpoint_is_a_clear_error(tmp_path):
    with pytest.raises(FileNotFoundError, match="no such checkpoint"):
        load_agent(tmp_path / "nope.pt")
    bad = tmp_path / "bad.pt"
    torch.save({"hello": 1}, bad)
    with pytest.raises(ValueError, match="not a seq2seq Driver checkpoint"):
        load_agent(bad)


def test_evaluation_has_the_baselines_json_and_csv_shape(trained, bench, few, tmp_path):
    _, out, _ = trained
    results = evaluate_checkpoint(bench, few["world"], out / "best.pt", "val_seen", instances=few["val"])
    ours = summarize("val_seen", results)
    theirs = summarize(
        "val_seen", evaluate_baselines(bench, "val_seen", ["stop"], instances=few["val"], progress=False)
    )
    assert ours.keys() == theirs.keys() and ours["n"] == len(few["val"])
    ((name, stats),) = ours["agents"].items()
    assert name == "seq2seq-baseline-teacher-none"
    assert stats.keys() == theirs["agents"]["stop"].keys()
    assert all(np.isfinite(stats[k]) for k in ("td_mean", "otd_mean", "sr", "spl", "steps_mean"))
    assert stats["otd_mean"] <= stats["td_mean"]
    write_csv(tmp_path / "per.csv", results)
    assert (tmp_path / "per.csv").read_text().splitlines()[0].split(",") == list(CSV_COLUMNS)


def test_vision_blind_agent_ignores_observations_and_language_blind_ignores_the_dialog(trained, bench, few):
    _, out, _ = trained
    agent, _, _ = load_agent(out / "last.pt")
    world, eps = few["world"], few["val_set"]
    scrambled = dataclasses.replace(world, obs=np.random.default_rng(0).random(world.obs.shape).astype(np.float16))
    silent = dataclasses.replace(
        eps, tokens=np.random.default_rng(1).integers(1, len(few["tokenizer"]), eps.tokens.shape)
    )
    idx = np.arange(len(eps))
    with torch.no_grad():
        act = lambda w, e, blind: run_episodes(agent, w, e, idx, "argmax", blind).actions  # noqa: E731
        assert (act(world, eps, "vision") == act(scrambled, eps, "vision")).all()
        assert (act(world, eps, "language") == act(world, silent, "language")).all()
        assert not (act(world, eps, "none") == act(scrambled, eps, "none")).all()


def _rays_at(table, node: int, heading: int):
    """The simulator's ray observation at a pose, as the Driver's frame there carries it."""
    from sim.core.rays import RayObservation

    at = (node, heading)
    return RayObservation(
        table.labels[at], table.depth[at], table.too_close[at], np.ones(13, dtype=bool), bool(table.forward_blocked[at])
    )


def _heard(inst):
    from sim.trial.percepts import Heard
    from sim.trial.vocabulary import Role as Speaker

    return [Heard(Speaker.COMMANDER if role == "oracle" else Speaker.DRIVER, text) for role, text in inst.dialog]


def test_seq2seq_driver_plays_from_a_growing_dialog(trained, bench, few):
    from models.driver import Seq2SeqDriver
    from sim.core.dynamics import Action
    from sim.core.observations import RayTable
    from sim.trial.agent import SeatInfo
    from sim.trial.commands import Claim, RequestMove, Say
    from sim.trial.percepts import Claimed, Judged, Moved, PhaseBegan, Saw
    from sim.trial.vocabulary import Move, Outcome, Phase, Role

    _, out, _ = trained
    inst = few["val"][0]
    graph = bench.graph(inst.run)
    node, heading = np.argwhere(graph.forward < 0)[0]
    blocked = _rays_at(RayTable.build(bench.maze(inst.run), graph), int(node), int(heading))
    driver = Seq2SeqDriver(out / "last.pt")
    driver.reset(SeatInfo(Role.DRIVER, 3))
    heard = _heard(inst)
    assert driver.perceive(PhaseBegan(Phase.LOCALIZING, 0, 3)) == []
    assert [driver.perceive(h) for h in heard[:3]] == [[]] * 3  # being localized, it holds still
    assert driver.perceive(Saw(1, blocked)) == []
    turns = driver.perceive(PhaseBegan(Phase.NAVIGATING, 0, 3))
    for n in (3, 5):
        assert turns and turns[-1] != RequestMove(Move.FORWARD)  # forward would collide here
        assert driver.encoded_for == (n, driver.named or "")
        for h in heard[n : n + 2]:
            assert driver.perceive(h) == []  # heard while its move is under way
        if isinstance(turns[-1], RequestMove):
            assert driver.perceive(Moved(turns[-1].move, Outcome.OK)) == []
            turns = driver.perceive(Saw(2, blocked))
        else:
            assert turns[-1] == Claim()
            driver.perceive(Claimed(0))
            turns = driver.perceive(Judged(False, 0))
    # Once it wants to stop it claims; after a rejected claim it moves before it claims again.
    with torch.no_grad():
        driver.agent.policy.bias[int(Action.STOP)] = 50.0
    if isinstance(turns[-1], RequestMove):
        assert driver.perceive(Moved(turns[-1].move, Outcome.OK)) == []
        turns = driver.perceive(Saw(3, blocked))
    assert turns[-1] == Claim() and turns[0] == Say(
        f"I think I found the {driver.named}" if driver.named else "I think I found it"
    )
    assert driver.perceive(Claimed(0)) == []
    (move,) = driver.perceive(Judged(False, 0))
    assert isinstance(move, RequestMove) and move.move != Move.FORWARD
    assert driver.perceive(Moved(move.move, Outcome.OK)) == []
    assert driver.perceive(Saw(4, blocked))[-1] == Claim()


def test_the_web_driver_counts_its_poses_by_its_own_odometry_for_its_revisit_penalty(trained, bench, few):
    from models.driver import Seq2SeqDriver
    from sim.core.dynamics import Action, snap_pose
    from sim.core.observations import RayTable
    from sim.trial.agent import SeatInfo
    from sim.trial.commands import RequestMove
    from sim.trial.percepts import Moved, PhaseBegan, Saw
    from sim.trial.vocabulary import Outcome, Phase, Role

    _, out, _ = trained
    inst = few["val"][0]
    graph = bench.graph(inst.run)
    table = RayTable.build(bench.maze(inst.run), graph)
    start = next(node for node in range(len(graph.nodes)) if (graph.forward[node] >= 0).any())
    nodes = {}
    for penalty in (0.0, 20.0):
        driver = Seq2SeqDriver(out / "last.pt")
        driver.agent.config.revisit_penalty = penalty
        with torch.no_grad():
            driver.agent.policy.bias[int(Action.LEFT)] = 10.0  # it wants to turn left, always
            driver.agent.policy.bias[int(Action.STOP)] = -50.0
        driver.reset(SeatInfo(Role.DRIVER, 3))
        for h in _heard(inst):
            driver.perceive(h)
        pose = snap_pose(graph, *graph.nodes[start])
        nodes[penalty] = {pose.node}
        driver.perceive(Saw(0, _rays_at(table, pose.node, pose.heading)))
        (turn,) = driver.perceive(PhaseBegan(Phase.NAVIGATING, 0, 3))
        for k in range(12):
            assert isinstance(turn, RequestMove)
            pose, collided = graph.moves.step(pose, Action.of(turn.move))
            nodes[penalty].add(pose.node)
            driver.perceive(Moved(turn.move, Outcome.COLLISION if collided else Outcome.OK))
            (turn,) = driver.perceive(Saw(k + 1, _rays_at(table, pose.node, pose.heading)))
    assert nodes[0.0] == {start}
    assert len(nodes[20.0]) >= 2  # round once, then away from the poses it has been in

"""`robotslang demo`: scripted Commander and Driver play whole trials over the real sockets."""

from __future__ import annotations

import math

import pytest
from sqlalchemy import select
from typer.testing import CliRunner

from app.cli import root
from app.db.engine import make_engine, make_sessionmaker
from app.db.models import Team, Trial
from app.demo.script import OBJECT_WORDS, describe_view, plan_leg
from app.mazes import Mazes
from app.trial.log import EventLog
from sim.core.dynamics import Action, Pose, snap_pose, teacher_action
from tests.app.live import UNPACED_ENV


@pytest.fixture(scope="module")
def demo_dir(tmp_path_factory):
    """Two demo trials played by the CLI, with the app served on its own loopback port."""
    data = tmp_path_factory.mktemp("demo") / "var"
    env = {
        "ROBOTSLANG_DATA_DIR": str(data),
        "ROBOTSLANG_SECRET_KEY": "demo-test",
        **UNPACED_ENV,
    }
    result = CliRunner().invoke(
        root, ["demo", "--trials", "2", "--parallel", "2", "--pace", "0", "--seed", "3"], env=env
    )
    assert result.exit_code == 0, result.output
    return data, env, result.output


def logged(data_dir):
    from app.settings import Settings

    settings = Settings(data_dir=data_dir, secret_key="demo-test")
    sessions = make_sessionmaker(make_engine(settings))
    with sessions() as db:
        trials = db.scalars(select(Trial).order_by(Trial.id)).all()
        teams = {t.id: t.name for t in db.scalars(select(Team))}
    log = EventLog(sessions)
    return settings, trials, teams, {t.id: log.load(t.id) for t in trials}


@pytest.mark.slow
def test_demo_trials_finish_with_every_target_truly_reached(demo_dir):
    data, _, output = demo_dir
    settings, trials, teams, events = logged(data)
    assert [t.phase for t in trials] == ["finished", "finished"]
    assert sorted(teams[t.team_id] for t in trials) == ["demo team 1", "demo team 2"]
    assert len({t.maze for t in trials}) == 2, "each demo team gets the least-used maze"
    for trial in trials:
        log = events[trial.id]
        kinds = [e.kind for e in log]
        assert kinds.count("connect") == 2 and "bad_message" not in kinds
        confirmed = [e.payload for e in log if e.kind == "target_confirmed"]
        assert [c["target"] for c in confirmed] == list(trial.targets)
        assert all(c["truly_within"] for c in confirmed)
        assert f"trial {trial.id}: maze {trial.maze}" in output and "finished" in output


def test_demo_dialog_is_route_words_from_both_seats(demo_dir):
    data, _, _ = demo_dir
    settings, trials, _, events = logged(data)
    for trial in trials:
        log = events[trial.id]
        chat = [(e.payload["role"], e.payload["text"]) for e in log if e.kind == "chat"]
        roles = {r for r, _ in chat}
        assert roles == {"commander", "driver"}
        commander_lines = [t for r, t in chat if r == "commander"]
        for target in trial.targets:
            assert f"go forward until you see the {OBJECT_WORDS[target]}" in commander_lines
        assert any(" wall" in t for t in commander_lines)
        # The Commander's estimate lands near the true start pose.
        start = next(e.payload for e in log if e.kind == "pose")
        estimate = next(e.payload for e in log if e.kind == "localization")
        assert math.dist((start["x"], start["y"]), (estimate["x"], estimate["y"])) < 0.25


def test_driver_follows_the_shortest_path_with_a_few_mistakes_and_questions(demo_dir):
    data, _, _ = demo_dir
    settings, trials, _, events = logged(data)
    mazes = Mazes(settings)
    moves = mistakes = questions = 0
    for trial in trials:
        maze, graph = mazes.load(trial.maze), mazes.graph(trial.maze)
        pose, target = None, 0
        for e in events[trial.id]:
            if e.kind == "pose":
                pose = snap_pose(graph, e.payload["x"], e.payload["y"], e.payload["heading"])
            elif e.kind == "target_confirmed":
                target = e.payload["target_index"] + 1
            elif e.kind == "move_requested":
                goal = graph.nearest_node(*maze.objects[trial.targets[target]])
                moves += 1
                mistakes += teacher_action(graph, pose, goal).word != e.payload["action"]
            elif e.kind == "chat" and e.payload["role"] == "driver":
                questions += e.payload["text"].endswith("?")
    assert 0 < mistakes <= 0.1 * moves, (mistakes, moves)
    assert questions > 0


def test_route_words_follow_the_shortest_path(demo_dir):
    data, _, _ = demo_dir
    settings, trials, _, events = logged(data)
    mazes = Mazes(settings)
    trial = trials[0]
    maze, graph = mazes.load(trial.maze), mazes.graph(trial.maze)
    start = next(e.payload for e in events[trial.id] if e.kind == "pose")
    pose = Pose(graph.nearest_node(start["x"], start["y"]), 0)
    leg = plan_leg(maze, graph, pose, trial.targets[0])
    for action in leg.actions:
        pose, collided = graph.moves.step(pose, action)
        assert not collided
    assert pose == leg.end and pose.node == graph.nearest_node(*maze.objects[trial.targets[0]])
    turns = sum(a != Action.FORWARD for a in leg.actions)
    assert turns == 0 or any(line.startswith("turn") or "turn" in line for line in leg.instructions)
    assert leg.instructions[-1] == f"go forward until you see the {OBJECT_WORDS[trial.targets[0]]}"
    assert " ahead" in describe_view(maze, graph, leg.end)


def test_demo_against_a_server_that_is_not_there_names_it_and_creates_nothing(tmp_path):
    env = {"ROBOTSLANG_DATA_DIR": str(tmp_path / "var"), "ROBOTSLANG_SECRET_KEY": "k"}
    result = CliRunner().invoke(root, ["demo", "--trials", "1", "--server", "http://127.0.0.1:9"], env=env)
    assert result.exit_code == 1
    assert "--server http://127.0.0.1:9: no RobotSlang server answers there" in " ".join(result.output.split())
    _, trials, _, _ = logged(tmp_path / "var")
    assert trials == []

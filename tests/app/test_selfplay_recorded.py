"""`robotslang eval selfplay --record DIR`: whole trials with `agent:dialog` in both seats played
through the platform in worker processes, from the offline runner's starts and seeds, recorded as
ordinary trials that replay and export, and played as the offline runner plays them: one referee."""

from __future__ import annotations

import json
import math

import pytest
from sqlalchemy import select

from app.db.engine import make_engine, make_sessionmaker, open_database
from app.db.models import Event, Trial
from app.mazes import Mazes
from app.settings import Settings
from app.trial.setup import TrialSetupError, create_trial
from sim.agents.selfplay import library_trials
from sim.core.dynamics import continuous_pose, snap_pose
from sim.core.navgraph import NavGraph
from sim.tasks.library import BUNDLED_DIR, MazeLibrary
from tests.app.live import UNPACED_ENV, cli

LIBRARY = MazeLibrary(bundled=BUNDLED_DIR)

KEYS = {
    "trials",
    "completed",
    "targets_confirmed_mean",
    "moves_ratio",
    "messages_mean",
    "first_estimate_td_m",
    "false_confirmations",
    "first_mark_within_0_5m",
    "bumps_per_instruction",
    "seconds_per_trial",
}


def bundled_starts(n: int, seed: int = 0) -> dict[str, tuple[float, float, float]]:
    """The starts the offline runner gives the first `n` bundled mazes: what --record must start from."""
    mazes = [(name, LIBRARY.load(name)) for name in LIBRARY.names()[:n]]
    graphs = [NavGraph.for_robot(m) for _, m in mazes]
    return {
        spec.maze: continuous_pose(g, spec.start)
        for spec, g in zip(library_trials(mazes, graphs, seed), graphs, strict=True)
    }


SAME = ("maze", "targets_confirmed", "moves", "shortest", "messages", "first_estimate_td_m", "ended", "dialog")


def played(tmp_path, name, *args, env=None):
    """`eval selfplay ARGS` with its per-trial rows."""
    rows = tmp_path / f"{name}.jsonl"
    done = cli("eval", "selfplay", *args, "--per-trial", str(rows), "--json", env=env or {})
    assert done.returncode == 0, done.stderr[-2000:]
    return [json.loads(line) for line in rows.read_text().splitlines()]


@pytest.mark.slow
def test_recorded_selfplay_plays_each_val_seen_trial_as_the_offline_runner_does(tmp_path, benchmark_path):
    """The platform and the offline runner are one referee: the same trial from the same start,
    move for move and word for word (two recording processes, the default)."""
    split = ("--benchmark", str(benchmark_path), "--split", "val_seen", "--limit", "2")
    offline = played(tmp_path, "offline", *split)
    recorded = played(tmp_path, "recorded", *split, "--record", str(tmp_path / "var"))
    assert [r["maze"] for r in recorded] == [r["maze"] for r in offline]
    for on_platform, here in zip(recorded, offline, strict=True):
        assert {k: on_platform[k] for k in SAME} == {k: here[k] for k in SAME}


@pytest.mark.slow
def test_selfplay_through_the_trial_core_records_ordinary_trials(tmp_path):
    data = tmp_path / "var"
    env = {**UNPACED_ENV, "ROBOTSLANG_RENDER_PROCESSES": "0"}
    done = cli("eval", "selfplay", "--record", str(data), "--limit", "2", "--processes", "2", "--json", env=env)
    assert done.returncode == 0, done.stderr[-2000:]
    figures = json.loads(done.stdout.strip().splitlines()[-1])
    assert set(figures) == KEYS
    assert figures["trials"] == 2 and figures["first_estimate_td_m"] is not None
    # gen-000 and gen-001: the Commander once routed the robot through the paddle there.
    assert figures["completed"] == 1.0 and figures["false_confirmations"] == 0
    assert figures["moves_ratio"] > 0 and figures["messages_mean"] > 0

    settings = Settings(data_dir=data)
    engine = make_engine(settings)
    with make_sessionmaker(engine)() as db:
        trials = db.scalars(select(Trial).order_by(Trial.id)).all()
        logs = {
            t.maze: db.scalars(select(Event).where(Event.trial_id == t.id).order_by(Event.seq)).all() for t in trials
        }
    engine.dispose()
    # Both workers' trials are in the one database, each played to its end.
    assert len(trials) == 2
    for trial in trials:
        assert trial.phase in ("finished", "aborted")
        assert (trial.commander, trial.driver, trial.team_id) == ("agent:dialog", "agent:dialog", None)
    mazes = Mazes(settings)
    for maze, start in bundled_starts(2).items():
        events = logs[maze]
        assert {"chat", "localization", "move_executed", "frame"} <= {e.kind for e in events}
        # The trial is created with the offline runner's start, logged, and the robot is first seen
        # there: both runners drive the robot on the one graph (the landmarks block it).
        assert events[0].kind == "trial_created" and events[0].payload["start"] == pytest.approx(list(start))
        graph = mazes.graph(maze)
        x, y, heading = continuous_pose(graph, snap_pose(graph, *start))
        assert (x, y) == pytest.approx(start[:2])
        first = next(e.payload for e in events if e.kind == "pose")
        assert (first["x"], first["y"]) == pytest.approx((x, y))
        assert math.cos(first["heading"] - heading) == pytest.approx(1.0)

    exported = cli(
        "export",
        "all",
        "--format",
        "ndh",
        "--include-aborted",  # a trial the agents did not finish replays and exports all the same
        "--out",
        str(tmp_path / "ndh"),
        env={**env, "ROBOTSLANG_DATA_DIR": str(data)},
    )
    assert exported.returncode == 0, exported.stderr[-2000:]
    assert (tmp_path / "ndh" / "NDH-data").is_dir()


def test_record_refuses_a_seat_the_platform_has_no_agent_for(tmp_path):
    data = tmp_path / "var"
    done = cli(
        "eval", "selfplay", "--record", str(data), "--limit", "1", "--commander", "oracle", env={"COLUMNS": "200"}
    )
    assert done.returncode != 0
    assert "--commander" in done.stderr and "no Commander 'oracle'" in done.stderr
    assert not (data / "robotslang.db").exists()  # nothing was created


@pytest.mark.parametrize(
    ("backend", "start", "error"),
    [("sim", (math.nan, 1.0, 0.0), "is not a pose"), ("robot:1", (1.0, 1.0, 0.0), "for the simulator")],
)
def test_a_trial_start_must_be_a_pose_for_the_simulator(tmp_path, backend, start, error):
    settings = Settings(data_dir=tmp_path)
    sessions = open_database(settings)
    maze = LIBRARY.names()[0]
    with pytest.raises(TrialSetupError, match=error), sessions.begin() as db:
        create_trial(
            db,
            team_id=None,
            maze=maze,
            targets=["jar", "mug", "paddle"],
            backend=backend,
            driver="agent:dialog",
            commander="agent:dialog",
            commander_id=None,
            layouts={maze: maze},
            now_ns=0,
            agents={"agent:dialog": None},
            commanders={"agent:dialog": None},
            start=start,
        )
    with sessions() as db:
        assert db.scalars(select(Trial)).all() == []  # nothing recorded

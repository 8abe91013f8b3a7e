"""A demo trial, exported: MCAP opens in mcap's reader with every stream, and the NDH export
loads, evaluates and trains with the project's own tools exactly as the benchmark does."""

from __future__ import annotations

import base64
import json
from pathlib import Path

import cv2
import jsonschema
import numpy as np
import pytest
from mcap.reader import make_reader
from sqlalchemy import select
from typer.testing import CliRunner

from app.cli import root
from app.db.engine import make_engine, make_sessionmaker
from app.db.models import Trial
from app.export.mcap import CHANNELS, DERIVED_TOPICS, schemas
from app.mazes import Mazes
from app.settings import Settings
from app.trial.log import EventLog
from sim.tasks.benchmark import Benchmark, recorded_start
from tests.app.live import UNPACED_ENV


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """Two finished demo trials on two mazes, and the environment that points at their data."""
    data = tmp_path_factory.mktemp("recorded") / "var"
    env = {
        "ROBOTSLANG_DATA_DIR": str(data),
        "ROBOTSLANG_SECRET_KEY": "export-test",
        **UNPACED_ENV,
    }
    result = CliRunner().invoke(root, ["demo", "--trials", "2", "--pace", "0", "--seed", "7"], env=env)
    assert result.exit_code == 0, result.output
    settings = Settings(data_dir=data, secret_key="export-test")
    sessions = make_sessionmaker(make_engine(settings))
    with sessions() as db:
        trials = db.scalars(select(Trial).order_by(Trial.id)).all()
    assert [t.phase for t in trials] == ["finished", "finished"]
    log = EventLog(sessions)
    return env, settings, trials, {t.id: log.load(t.id) for t in trials}


def run(env, *args) -> str:
    """The command's standard output (progress bars go to standard error)."""
    result = CliRunner().invoke(root, list(args), env=env)
    assert result.exit_code == 0, result.output
    return result.stdout


def test_mcap_of_a_demo_trial_has_every_stream_and_every_event_once(recorded, tmp_path):
    env, settings, trials, events = recorded
    trial = trials[0]
    out = tmp_path / "trial.mcap"
    run(env, "export", str(trial.id), "--format", "mcap", "--out", str(out))
    with out.open("rb") as f:
        reader = make_reader(f)
        topics = {c.topic for c in reader.get_summary().channels.values()}
        messages = list(reader.iter_messages(log_time_order=True))
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
        attachments = {a.name for a in reader.iter_attachments()}
    assert topics == set(CHANNELS)
    for schema, _channel, message in messages:  # the published Foxglove schemas, and our own two
        jsonschema.validate(json.loads(message.data), schemas()[schema.name])
    log = events[trial.id]
    logged = [(c, m) for _, c, m in messages if c.topic not in DERIVED_TOPICS]
    assert sorted(m.sequence for _, m in logged) == [e.seq for e in log]
    assert [m.log_time for _, m in logged] == sorted(e.t_ns for e in log)
    per_topic = {}
    for _, channel, _ in messages:
        per_topic[channel.topic] = per_topic.get(channel.topic, 0) + 1
    for topic in (
        "/driver/camera",
        "/chat",
        "/driver/cmd",
        "/robot/pose/sim",
        "/commander/estimate",
        "/tf",
        "/maze/scene",
        "/trial/event",
    ):
        assert per_topic.get(topic, 0) > 0, f"{topic} has no messages"
    assert per_topic["/tf"] == per_topic["/robot/pose/sim"] == sum(e.kind == "pose" for e in log)
    assert per_topic["/commander/estimate"] == sum(e.kind == "localization" for e in log)
    frames = {e.seq: e for e in log if e.kind == "frame"}
    assert per_topic["/driver/camera"] == len(frames)
    for schema, channel, message in messages:
        if channel.topic != "/driver/camera":
            continue
        assert schema.name == "foxglove.CompressedImage"
        assert message.publish_time == frames[message.sequence].payload["capture_ns"]
        image = json.loads(message.data)
        decoded = cv2.imdecode(np.frombuffer(base64.b64decode(image["data"]), np.uint8), cv2.IMREAD_COLOR)
        assert decoded.shape == (240, 320, 3)
    assert metadata["trial"]["maze"] == trial.maze
    assert metadata["trial"]["targets"] == ",".join(trial.targets)
    assert metadata["trial"]["team"] == "demo team 1"
    assert attachments == {"maze.map-fixed.png", "maze.map.png"}


def test_export_all_mcap_writes_one_file_per_finished_trial(recorded, tmp_path):
    env, _, trials, _ = recorded
    result = CliRunner().invoke(root, ["export", "all", "--format", "mcap", "--out", str(tmp_path)], env=env)
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in tmp_path.glob("*.mcap")) == [f"trial-{t.id}.mcap" for t in trials]
    assert "2 trial(s)" in result.output


@pytest.mark.slow
def test_ndh_export_reads_evaluates_and_trains_like_the_benchmark(recorded, tmp_path):
    env, settings, trials, events = recorded
    out = tmp_path / "ndh"
    run(env, "export", "all", "--format", "ndh", "--out", str(out))
    bench = Benchmark(out)
    mazes = Mazes(settings)
    by_split = {s: bench.split(s) for s in ("train", "val_seen", "test")}
    instances = [i for split in by_split.values() for i in split]
    assert len(instances) == 6 and sorted(i.inst_idx for i in instances) == list(range(6))
    splits_of = {}
    for split, items in by_split.items():
        for inst in items:
            splits_of.setdefault(inst.run, set()).add(split)
    assert all(len(s) == 1 for s in splits_of.values()), "no maze in two folds"
    for trial in trials:
        maze = mazes.load(trial.maze)
        mine = sorted((i for i in instances if i.run == trial.maze), key=lambda i: i.inst_idx)
        assert [i.target for i in mine] == list(trial.targets)
        assert np.array_equal(bench.maze(trial.maze).labels, maze.labels)
        for i in mine:
            assert i.target_pose == pytest.approx(maze.objects[i.target])
        start = next(e.payload for e in events[trial.id] if e.kind == "pose")
        graph = bench.graph(trial.maze)
        assert recorded_start(graph, mine[0]).node == graph.nearest_node(start["x"], start["y"])
        assert mine[1].previous_object == pytest.approx(maze.objects[trial.targets[0]])
        # Each instance's dialog is the whole chat up to that target's confirmation.
        confirmations = [e.seq for e in events[trial.id] if e.kind == "target_confirmed"]
        for inst, confirmed_at in zip(mine, confirmations):
            said = [e.payload["text"] for e in events[trial.id] if e.kind == "chat" and e.seq < confirmed_at]
            assert [message for _, message in inst.dialog] == said

    split = next(s for s, items in by_split.items() if items)
    report = json.loads(
        run(env, "eval", "baselines", "--benchmark", str(out), "--split", split, "--agent", "stop,shortest", "--json")
    )
    assert report["n"] == len(by_split[split])
    assert report["agents"]["shortest"]["sr"] == 1.0
    assert report["agents"]["stop"]["td_mean"] > 0

    run(
        env,
        "train",
        "ndh",
        "--benchmark",
        str(out),
        "--iters",
        "1",
        "--eval-every",
        "1",
        "--out",
        str(tmp_path / "run"),
    )
    scored = json.loads(
        run(
            env,
            "eval",
            "ndh",
            "--benchmark",
            str(out),
            "--checkpoint",
            str(tmp_path / "run" / "last.pt"),
            "--split",
            "val_seen",
            "--json",
        )
    )
    assert scored["n"] == len(by_split["val_seen"]) > 0


def test_export_of_an_unknown_trial_names_it(recorded, tmp_path):
    env, _, _, _ = recorded
    result = CliRunner().invoke(root, ["export", "999", "--format", "mcap", "--out", str(tmp_path / "x.mcap")], env=env)
    assert result.exit_code == 1
    assert "no trial 999" in result.output
    assert not (tmp_path / "x.mcap").exists()


def test_export_without_a_database_says_where_it_looked(tmp_path):
    env = {"ROBOTSLANG_DATA_DIR": str(tmp_path / "empty")}
    result = CliRunner().invoke(root, ["export", "all", "--format", "ndh", "--out", str(tmp_path / "o")], env=env)
    assert result.exit_code == 1
    assert f"no database at {tmp_path / 'empty' / 'robotslang.db'}" in " ".join(result.output.split())


@pytest.mark.slow
def test_demo_and_exports_on_postgresql(postgres_url, tmp_path):
    env = {
        "ROBOTSLANG_DATA_DIR": str(tmp_path / "var"),
        "ROBOTSLANG_DATABASE_URL": postgres_url,
        "ROBOTSLANG_SECRET_KEY": "pg-test",
        **UNPACED_ENV,
    }
    run(env, "demo", "--trials", "1", "--pace", "0")
    settings = Settings(data_dir=tmp_path / "var", database_url=postgres_url, secret_key="pg-test")
    sessions = make_sessionmaker(make_engine(settings))
    with sessions() as db:
        (trial,) = db.scalars(select(Trial)).all()
    log = EventLog(sessions).load(trial.id)
    run(env, "export", "all", "--format", "mcap", "--out", str(tmp_path / "mcap"))
    with (tmp_path / "mcap" / f"trial-{trial.id}.mcap").open("rb") as f:
        seqs = sorted(m.sequence for _, c, m in make_reader(f).iter_messages() if c.topic not in DERIVED_TOPICS)
    assert seqs == [e.seq for e in log]
    run(env, "export", "all", "--format", "ndh", "--out", str(tmp_path / "ndh"))
    assert [i.target for i in Benchmark(tmp_path / "ndh").split("train")] == list(trial.targets)


LAYOUT = Path(__file__).resolve().parents[2] / "docs" / "foxglove" / "robotslang-layout.json"


def layout_topics(node) -> set[str]:
    """Every topic the layout names: topic settings' keys, image/log/raw topics, plot paths."""
    found: set[str] = set()
    if isinstance(node, dict):
        for key, value in node.items():
            if key == "topics" and isinstance(value, dict):
                found |= set(value)
            elif key in ("imageTopic", "topicToRender", "topicPath", "value") and isinstance(value, str):
                found.add(value.split(".", 1)[0])
            found |= layout_topics(value)
    elif isinstance(node, list):
        for item in node:
            found |= layout_topics(item)
    return found


def test_foxglove_layout_names_only_topics_a_recording_has(recorded, tmp_path):
    env, _, trials, _ = recorded
    layout = json.loads(LAYOUT.read_text())
    panels = {p["panelType"] for p in _panels(layout["content"])}
    assert {"Image", "ThreeDee", "Log", "Plot"} <= panels
    out = tmp_path / "trial.mcap"
    run(env, "export", str(trials[0].id), "--format", "mcap", "--out", str(out))
    with out.open("rb") as f:
        topics = {c.topic for c in make_reader(f).get_summary().channels.values()}
    named = layout_topics(layout)
    assert {"/driver/camera", "/chat", "/maze/scene", "/commander/estimate", "/driver/cmd"} <= named
    assert named <= topics, f"the layout names topics no recording has: {sorted(named - topics)}"


def _panels(node) -> list[dict]:
    if node.get("type") == "panel":
        return [node]
    return [p for item in node.get("items", []) for p in _panels(item["content"])]

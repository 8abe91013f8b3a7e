"""LeRobotDataset v3 export of a demo trial: the layout LeRobot reads, checked against the log,
and loaded back with lerobot's own `LeRobotDataset`, in the venv `make lerobot-venv` builds."""

from __future__ import annotations

import json
import os
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest
from sqlalchemy import select
from typer.testing import CliRunner

from app.cli import root
from app.db.engine import make_engine, make_sessionmaker
from app.db.models import Trial
from app.export.lerobot import FPS, STATE_NAMES, VIDEO_KEY, Episode, episodes_of, write_lerobot
from app.export.record import ExportError
from app.settings import Settings
from app.trial.log import EventLog
from sim.core.dynamics import Action
from tests.app.live import UNPACED_ENV
from tests.app.trial_log import small_maze
from tests.packaging.outside import REPO, clean_env

av = pytest.importorskip("av", reason="the LeRobot export needs the `lerobot` extra (PyAV)")
pq = pytest.importorskip("pyarrow.parquet", reason="the LeRobot export needs the `lerobot` extra (pyarrow)")


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    data = tmp_path_factory.mktemp("lerobot") / "var"
    env = {
        "ROBOTSLANG_DATA_DIR": str(data),
        "ROBOTSLANG_SECRET_KEY": "lerobot-test",
        **UNPACED_ENV,
    }
    result = CliRunner().invoke(root, ["demo", "--trials", "1", "--pace", "0", "--seed", "5"], env=env)
    assert result.exit_code == 0, result.output
    sessions = make_sessionmaker(make_engine(Settings(data_dir=data, secret_key="lerobot-test")))
    with sessions() as db:
        (trial,) = db.scalars(select(Trial)).all()
    return env, trial, EventLog(sessions).load(trial.id)


def export(env, out, *flags) -> None:
    result = CliRunner().invoke(root, ["export", "all", "--format", "lerobot", "--out", str(out), *flags], env=env)
    assert result.exit_code == 0, result.output


def driver_steps(log):
    """What the dataset must hold, from the log: each Driver frame and the move executed after it."""
    steps, pending = [], None
    for e in log:
        if e.kind == "frame" and e.payload.get("source", "driver") == "driver":
            pending = [e, Action.STOP]
        elif e.kind == "move_executed" and pending is not None:
            pending[1] = Action.of(e.payload["action"])
            steps.append(pending)
            pending = None
    return steps + ([pending] if pending else [])


@pytest.mark.slow
@pytest.mark.parametrize("per", ["ndh", "trial"])
def test_layout_frames_actions_and_dialog_match_the_log(recorded, tmp_path, per):
    env, trial, log = recorded
    out = tmp_path / "ds"
    export(env, out, "--episode", per)
    info = json.loads((out / "meta/info.json").read_text())
    assert info["codebase_version"] == "v3.0"
    episodes = pq.read_table(out / "meta/episodes/chunk-000/file-000.parquet").to_pylist()
    assert info["total_episodes"] == len(episodes) == (3 if per == "ndh" else 1)
    data = pq.read_table(out / info["data_path"].format(chunk_index=0, file_index=0)).to_pylist()
    assert info["total_frames"] == len(data)
    tasks = pq.read_table(out / "meta/tasks.parquet").to_pandas()
    task_of = {int(i): t for t, i in zip(tasks.index, tasks["task_index"])}
    assert set(task_of.values()) == set(trial.targets)

    steps = driver_steps(log)
    assert [r["frame_seq"] for r in data] == [f.seq for f, _ in steps]
    confirmed = [e.seq for e in log if e.kind == "target_confirmed"]
    for row, (frame, action) in zip(data, steps):
        ends_episode = row["index"] == episodes[row["episode_index"]]["dataset_to_index"] - 1
        assert row["action"] == (Action.STOP if ends_episode else action)
        assert task_of[row["task_index"]] == trial.targets[sum(c < frame.seq for c in confirmed)]
        assert len(row["observation.state"]) == len(STATE_NAMES)
    # Every chat message once, with its speaker and time, in log order.
    said = [m for r in data for m in json.loads(r["language.messages"])]
    chats = [e for e in log if e.kind == "chat"]
    assert [(m["speaker"], m["text"], m["t_ns"]) for m in said] == [
        (e.payload["role"], e.payload["text"], e.t_ns) for e in chats
    ]
    # The video: one decoded frame per row, close to the recorded JPEG.
    first = episodes[0]
    video = out / info["video_path"].format(
        video_key=VIDEO_KEY, chunk_index=0, file_index=first[f"videos/{VIDEO_KEY}/file_index"]
    )
    with av.open(str(video)) as container:
        decoded = [(f.time, f.to_ndarray(format="rgb24")) for f in container.decode(video=0)]
    assert len(decoded) == first["length"]
    # LeRobot finds a row's image by its timestamp, to within 1e-4 s by default.
    rows = [r for r in data if r["episode_index"] == 0]
    assert np.allclose([t for t, _ in decoded], [r["timestamp"] for r in rows], atol=1e-4, rtol=0)
    decoded = [image for _, image in decoded]
    frames_dir = Settings(data_dir=env["ROBOTSLANG_DATA_DIR"], secret_key="x").frames_dir
    recorded_rgb = cv2.cvtColor(cv2.imread(str(frames_dir / steps[0][0].payload["path"])), cv2.COLOR_BGR2RGB)
    assert decoded[0].shape == recorded_rgb.shape == tuple(info["features"][VIDEO_KEY]["shape"])
    assert np.abs(decoded[0].astype(int) - recorded_rgb).mean() < 8


@pytest.mark.slow
def test_an_independent_v3_checker_finds_the_format_compliant(recorded, tmp_path):
    doctor = pytest.importorskip("lerobot_doctor.runner", reason="lerobot-doctor (the `lerobot` extra)")
    from lerobot_doctor.dataset_loader import load_local

    env, _, _ = recorded
    out = tmp_path / "ds"
    export(env, out)
    # The format checks pass outright; the rest judge the data (a demo's actions repeat): no FAIL.
    formats = ["metadata", "temporal", "videos", "consistency", "training", "portability"]
    report = doctor.run_checks(load_local(out), checks=formats)
    assert (report.codebase_version, report.format_version) == ("v3.0", "v3")
    assert {
        r.name: [m.message for m in r.messages if m.severity is not doctor.Severity.PASS]
        for r in report.results
        if r.severity is not doctor.Severity.PASS
    } == {}
    assert len(report.results) == len(formats)
    full = doctor.run_checks(load_local(out))
    assert [r.name for r in full.results if r.severity is doctor.Severity.FAIL] == []


def lerobot_python() -> Path:
    """The lerobot venv's Python: $ROBOTSLANG_LEROBOT_PYTHON (CI sets it, so a broken one fails),
    else the one `make lerobot-venv` builds, else skip."""
    configured = os.environ.get("ROBOTSLANG_LEROBOT_PYTHON")
    if configured:
        return Path(configured)
    built = REPO / ".venv-lerobot" / "bin" / "python"
    if not built.exists():
        pytest.skip(
            "lerobot's LeRobotDataset runs in a venv of its own (lerobot 0.4.4 imports torchvision, and "
            "none on this index loads beside torch 2.13.0+cpu): `make lerobot-venv` builds it, .ci/run does"
        )
    return built


@pytest.mark.slow
def test_lerobot_loads_it_back(recorded, tmp_path):
    python = lerobot_python()
    env, trial, log = recorded
    out, served = tmp_path / "ds", tmp_path / "served"
    export(env, out)
    served.mkdir()
    loaded = subprocess.run(
        [str(python), str(Path(__file__).with_name("lerobot_env") / "load_back.py"), str(out), str(served)],
        # Offline, with the datasets cache in the test's folder: nothing to fetch, nothing left behind.
        env=clean_env(HF_HUB_OFFLINE="1", HF_HOME=str(tmp_path / "hf")),
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert loaded.returncode == 0, loaded.stderr
    report = json.loads((served / "items.json").read_text())
    steps = driver_steps(log)
    assert (report["num_frames"], report["num_episodes"], report["fps"]) == (len(steps), 3, FPS)
    assert report["video_keys"] == [VIDEO_KEY]
    items = report["items"]
    assert [it["frame_seq"] for it in items] == [f.seq for f, _ in steps]
    confirmed = [e.seq for e in log if e.kind == "target_confirmed"]
    for i, (item, (frame, action)) in enumerate(zip(items, steps)):
        # An NDH instance ends at its target's confirmation; its last frame's action is STOP.
        assert item["episode_index"] == sum(c < frame.seq for c in confirmed[:-1])
        ends_episode = i == len(items) - 1 or items[i + 1]["episode_index"] != item["episode_index"]
        assert item["action"] == (Action.STOP if ends_episode else action)
        assert item["task"] == trial.targets[sum(c < frame.seq for c in confirmed)]
    said = [m for it in items for m in json.loads(it["language.messages"])]
    assert [(m["speaker"], m["text"], m["t_ns"]) for m in said] == [
        (e.payload["role"], e.payload["text"], e.t_ns) for e in log if e.kind == "chat"
    ]
    # Every image LeRobot decodes (at its item's timestamp) is the Driver's recorded frame.
    images = np.load(served / f"{VIDEO_KEY}.npy")
    frames_dir = Settings(data_dir=env["ROBOTSLANG_DATA_DIR"], secret_key="x").frames_dir
    assert images.shape[0] == len(steps)
    for image, (frame, _) in zip(images, steps):
        recorded_rgb = cv2.cvtColor(cv2.imread(str(frames_dir / frame.payload["path"])), cv2.COLOR_BGR2RGB)
        assert image.transpose(1, 2, 0).shape == recorded_rgb.shape
        assert np.abs(image.transpose(1, 2, 0).astype(int) - recorded_rgb).mean() < 8, frame.seq


@pytest.mark.slow
def test_refuses_a_folder_with_something_in_it(recorded, tmp_path):
    env, _, _ = recorded
    (tmp_path / "ds").mkdir()
    (tmp_path / "ds" / "notes.txt").write_text("mine")
    result = CliRunner().invoke(root, ["export", "all", "--format", "lerobot", "--out", str(tmp_path / "ds")], env=env)
    assert result.exit_code == 1 and "is not empty" in result.output
    assert (tmp_path / "ds" / "notes.txt").read_text() == "mine"


def test_a_missing_frame_file_names_it_and_leaves_nothing(record, tmp_path):
    (tmp_path / "frames" / "2.jpg").unlink()
    out = tmp_path / "ds"
    with pytest.raises(ExportError, match=r"trial 7: frame 2 .*frames/2\.jpg"):
        write_lerobot([(record, small_maze())], out)
    assert not out.exists() and not (tmp_path / "ds.part").exists()


def test_steps_pair_each_driver_frame_with_the_move_after_it(record):
    (episode,) = episodes_of(record, small_maze(), Episode.trial)
    assert [(s.frame.seq, s.action) for s in episode] == [(6, Action.FORWARD), (12, Action.STOP)]
    assert [s.state[:2] for s in episode] == [[0.5, 0.6], [0.5, 0.67]]
    assert episode[0].task == "mug"
    # The chat between the first frame and the second is on the first, in log order.
    assert [m["text"] for m in episode[0].messages] == ["what do you see?", "a red wall"]

"""A small recorded trial on a small maze, as the exports read it."""

from __future__ import annotations

import math

import cv2
import numpy as np

from app.export.record import TrialRecord
from sim.core.labels import Label
from sim.core.maze import Maze
from sim.trial.state import LoggedEvent


def small_maze() -> Maze:
    labels = np.zeros((1175, 1401), np.uint8)
    labels[:12, :], labels[-12:, :] = Label.RED, Label.BLUE
    labels[:, :12], labels[:, -12:] = Label.GREEN, Label.YELLOW
    labels[300:330, 200:230], labels[800:830, 900:930] = Label.JAR, Label.MUG
    labels[500:530, 1200:1230] = Label.PADDLE
    return Maze.from_labels(labels, "test-maze")


def jpeg(shade: int) -> bytes:
    image = np.full((48, 64, 3), shade, np.uint8)
    return cv2.imencode(".jpg", image)[1].tobytes()


def trial_record(tmp_path) -> TrialRecord:
    """A finished trial's record, its frames written under `tmp_path`."""
    (tmp_path / "frames").mkdir()
    raw = [
        (
            "trial_created",
            {"maze": "test-maze", "targets": ["mug", "jar", "paddle"], "backend": "sim", "driver": "human"},
        ),
        ("connect", {"role": "commander"}),
        ("connect", {"role": "driver"}),
        ("phase", {"phase": "localizing", "target_index": 0}),
        ("pose", {"x": 0.5, "y": 0.6, "heading": np.pi / 2, "source": "sim"}),
        (
            "frame",
            {
                "frame_id": 1,
                "source": "driver",
                "path": "frames/1.jpg",
                "capture_ns": None,
                "width": 64,
                "height": 48,
                "mime": "image/jpeg",
            },
        ),
        ("chat", {"role": "commander", "text": "what do you see?"}),
        ("chat", {"role": "driver", "text": "a red wall"}),
        ("move_requested", {"move_id": 1, "action": "forward"}),
        ("move_executed", {"move_id": 1, "action": "forward", "outcome": "ok", "collision": False}),
        ("pose", {"x": 0.5, "y": 0.67, "heading": np.pi / 2, "source": "sim"}),
        (
            "frame",
            {
                "frame_id": 2,
                "source": "driver",
                "path": "frames/2.jpg",
                "capture_ns": None,
                "width": 64,
                "height": 48,
                "mime": "image/jpeg",
            },
        ),
        (
            "frame",
            {
                "frame_id": 3,
                "source": "overhead",
                "path": "frames/3.jpg",
                "capture_ns": None,
                "width": 64,
                "height": 48,
                "mime": "image/jpeg",
            },
        ),
        ("localization", {"x": 0.55, "y": 0.6, "heading": None}),
        ("phase", {"phase": "navigating", "target_index": 0}),
    ]
    events, t0 = [], 1_700_000_000_000_000_000
    for seq, (kind, payload) in enumerate(raw, start=1):
        t = t0 + seq * 10_000_000
        if kind == "frame":
            payload = {**payload, "capture_ns": t - 4_000_000}
            (tmp_path / payload["path"]).write_bytes(jpeg(40 * payload["frame_id"]))
        events.append(LoggedEvent(seq=seq, kind=kind, t_ns=t, payload=payload))
    # The log is stored by seq; a writer must not rely on arrival order matching the clock.
    events[5], events[6] = events[6], events[5]
    return TrialRecord(
        trial_id="7",
        team="blue team",
        maze="test-maze",
        targets=("mug", "jar", "paddle"),
        events=tuple(events),
        frames_root=tmp_path,
    )


def maze_named(name: str, shift: int = 0) -> Maze:
    labels = np.zeros((1175, 1401), np.uint8)
    labels[:12, :], labels[-12:, :] = Label.RED, Label.BLUE
    labels[:, :12], labels[:, -12:] = Label.GREEN, Label.YELLOW
    labels[300:330, 200 + shift : 230 + shift] = Label.JAR
    labels[800:830, 900:930], labels[500:530, 1200:1230] = Label.MUG, Label.PADDLE
    return Maze.from_labels(labels, name)


def ndh_trial_record(
    trial_id: str, maze: str, targets=("jar", "mug", "paddle"), confirmed=3, with_pose=True
) -> TrialRecord:
    """A finished sim trial's record on `maze`: dialog, a tracked pose (or none), `confirmed` targets found."""
    raw = [
        ("trial_created", {"maze": maze, "targets": list(targets), "backend": "sim", "driver": "human"}),
        ("chat", {"role": "commander", "text": "hello before the start"}),
        ("phase", {"phase": "localizing", "target_index": 0}),
    ]
    if with_pose:
        raw.append(("pose", {"x": 0.5, "y": 0.6, "heading": -math.pi / 2, "source": "sim"}))
    raw += [
        ("chat", {"role": "commander", "text": "what do you see?"}),
        ("chat", {"role": "driver", "text": "a red wall"}),
        ("move_requested", {"move_id": 1, "action": "forward"}),
    ]
    if with_pose:
        raw.append(("pose", {"x": 0.5, "y": 0.53, "heading": -math.pi / 2, "source": "sim"}))
    raw += [
        ("localization", {"x": 0.45, "y": 0.5, "heading": None}),
        ("phase", {"phase": "navigating", "target_index": 0}),
    ]
    for k in range(confirmed):
        raw += [
            ("chat", {"role": "commander", "text": f"go to the {targets[k]}"}),
            ("chat", {"role": "driver", "text": f"found the {targets[k]}"}),
            ("target_claimed", {"target": targets[k], "target_index": k, "frame_id": k}),
            ("target_confirmed", {"target": targets[k], "target_index": k, "within_m": 0.1, "truly_within": True}),
        ]
    raw.append(("chat", {"role": "driver", "text": "after the last target"}))
    events = tuple(
        LoggedEvent(seq=i, kind=k, t_ns=10**18 + i * 10**7, payload=p) for i, (k, p) in enumerate(raw, start=1)
    )
    return TrialRecord(trial_id=trial_id, team="t", maze=maze, targets=tuple(targets), events=events, frames_root=None)

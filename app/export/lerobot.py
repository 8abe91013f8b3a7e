"""Recorded trials as a LeRobotDataset v3 (codebase_version v3.0), written with pyarrow and PyAV.

One episode per NDH instance (`Episode.ndh`: from the previous target's confirmation to this
one's) or per trial (`Episode.trial`). A frame is one Driver step: the Driver's camera image
(`observation.images.front`, H.264 video), `observation.state` = [x, y, heading, 13 ray depths
(m), 13 ray labels] at that frame, `action` = the move executed next (`sim.core.dynamics.Action`;
STOP on an episode's last frame), the task = the target being sought. LeRobot 0.4.4 has no
language columns, so the dialog is a per-frame string feature, `language.messages`: a JSON list
of `{speaker, text, t_ns, seq}` for every chat message logged since the previous frame (before
the first frame: on the first; after the last: on the last), so each message is in exactly one
frame. Layout (lerobot `datasets/utils.py`): meta/info.json, meta/stats.json,
meta/tasks.parquet, meta/episodes/chunk-000/file-000.parquet, data/chunk-000/file-000.parquet,
videos/observation.images.front/chunk-000/file-NNN.mp4 (one file per episode).
"""

from __future__ import annotations

import json
import math
import shutil
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypedDict

import cv2
import numpy as np

from app.export import Episode
from app.export.record import ExportError, TrialRecord
from sim.core.dynamics import Action
from sim.core.maze import Maze
from sim.core.observations import N_RAYS, cast_rays
from sim.trial import events as ev
from sim.trial.state import LoggedEvent
from sim.trial.vocabulary import Move

CODEBASE_VERSION = "v3.0"
FPS = 10  # nominal: a frame is a Driver step, not a clock tick
VIDEO_KEY = "observation.images.front"
STATE_NAMES = (
    ["x", "y", "heading"] + [f"ray_depth_{i}" for i in range(N_RAYS)] + [f"ray_label_{i}" for i in range(N_RAYS)]
)
DATA_FILE = "data/chunk-000/file-000.parquet"
EPISODES_FILE = "meta/episodes/chunk-000/file-000.parquet"
VIDEO_PATH = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
# The data file's columns in its order, with their dtypes, and the shape and names of those not scalar.
COLUMNS = {
    "observation.state": "float32",
    "action": "int64",
    "language.messages": "string",
    "frame_seq": "int64",
    "trial_id": "int64",
    "timestamp": "float32",
    "frame_index": "int64",
    "episode_index": "int64",
    "index": "int64",
    "task_index": "int64",
}
SHAPES = {"observation.state": ([len(STATE_NAMES)], STATE_NAMES), "action": ([1], [a.word for a in Action])}


class ChatMessage(TypedDict):
    """One message of `language.messages`."""

    speaker: str
    text: str
    t_ns: int
    seq: int


class Annotation(TypedDict):
    """An episode's `annotation` (as a JSON string): the trial's dialog phenomena, anchored to
    message numbers from 1, and the end of localization where one was marked."""

    tags: dict[str, list[int]]
    localized_after_message: int | None
    localization_source: str | None


@dataclass
class Step:
    frame: LoggedEvent
    state: list[float]
    action: Action
    task: str
    messages: list[ChatMessage] = field(default_factory=list)


def _chat(event: LoggedEvent) -> ChatMessage:
    p = event.payload
    return {"speaker": p.get("role", ""), "text": p.get("text", ""), "t_ns": event.t_ns, "seq": event.seq}


def _state(maze: Maze, pose: LoggedEvent | None) -> list[float]:
    """The state at the last true pose logged (NaN before any)."""
    if pose is None:
        return [math.nan] * len(STATE_NAMES)
    p = pose.payload
    x, y, heading = float(p["x"]), float(p["y"]), float(p.get("heading") or 0.0)
    labels, depth = cast_rays(maze, x, y, heading)
    return [x, y, heading, *map(float, depth), *map(float, labels)]


def episodes_of(record: TrialRecord, maze: Maze, per: Episode) -> list[list[Step]]:
    """The trial's episodes as Driver steps, with the dialog spread over them."""
    events = sorted(record.events, key=lambda e: e.seq)
    confirmed = [e.seq for e in events if e.is_(ev.TargetConfirmed)]
    steps: list[Step] = []
    pose: LoggedEvent | None = None
    pending: Step | None = None
    for event in events:
        if event.is_(ev.PoseSampled):
            pose = event
        elif event.is_(ev.FrameRecorded) and event.payload.get("source", "driver") == "driver":
            reached = sum(c < event.seq for c in confirmed)
            task = record.targets[min(reached, len(record.targets) - 1)]
            pending = Step(event, _state(maze, pose), Action.STOP, task)
        elif event.is_(ev.MoveExecuted) and pending is not None:
            pending.action = Action.of(Move(event.payload["action"]))
            steps.append(pending)
            pending = None
    if pending is not None:
        steps.append(pending)
    if not steps:
        raise ExportError(f"trial {record.trial_id}: no Driver camera frames to make episodes of")
    # Episode boundaries: each confirmation closes one (NDH); the trial is one otherwise.
    bounds = confirmed[:-1] if per is Episode.ndh else []
    groups: list[list[Step]] = [[] for _ in range(len(bounds) + 1)]
    for step in steps:
        groups[sum(b < step.frame.seq for b in bounds)].append(step)
    groups = [g for g in groups if g]
    for group in groups:
        group[-1].action = Action.STOP
    for event in events:
        if event.is_(ev.Chat):
            before = [s for s in steps if s.frame.seq <= event.seq]
            (before[-1] if before else steps[0]).messages.append(_chat(event))
    return groups


def _decode(jpeg: bytes) -> np.ndarray:
    image = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
    if image is None:
        raise ExportError("a Driver camera frame is not an image")
    return np.asarray(image)


def _encode_video(path: Path, images: Sequence[bytes]) -> tuple[int, int]:
    import av

    path.parent.mkdir(parents=True, exist_ok=True)
    frames = [_decode(b) for b in images]
    height, width = frames[0].shape[:2]
    with av.open(str(path), "w") as container:
        stream = container.add_stream("libx264", rate=FPS)
        stream.width, stream.height, stream.pix_fmt = width, height, "yuv420p"
        stream.options = {"g": "2", "crf": "18"}
        for image in frames:
            if image.shape[:2] != (height, width):
                image = cv2.resize(image, (width, height))
            rgb = np.asarray(cv2.cvtColor(image, cv2.COLOR_BGR2RGB), dtype=np.uint8)  # uint8 already: no copy
            frame = av.VideoFrame.from_ndarray(rgb, format="rgb24")
            for packet in stream.encode(frame):
                container.mux(packet)
        for packet in stream.encode():
            container.mux(packet)
    return height, width


def _stats(values: np.ndarray) -> dict[str, list[Any]]:
    values = values.reshape(len(values), -1).astype(np.float64)
    return {
        "min": np.nanmin(values, 0).tolist(),
        "max": np.nanmax(values, 0).tolist(),
        "mean": np.nanmean(values, 0).tolist(),
        "std": np.nanstd(values, 0).tolist(),
        "count": [len(values)],
    }


def write_lerobot(
    loaded: Iterable[tuple[TrialRecord, Maze]], out: str | Path, per: Episode = Episode.ndh
) -> dict[str, int]:
    """Write every trial's episodes to the folder `out` (new or empty), built in `out.part` and
    renamed when complete; returns the totals."""
    out = Path(out)
    if out.exists() and any(out.iterdir()):
        raise ExportError(f"{out} is not empty: a LeRobot dataset needs a folder of its own")
    tmp = out.with_name(out.name + ".part")
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        totals = _write(loaded, tmp, per)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)  # never leave half a dataset
        raise
    tmp.replace(out)
    return totals


def _annotation(record: TrialRecord) -> Annotation:
    after = record.localized_after
    return {
        "tags": record.tags,
        "localized_after_message": after[0] if after else None,
        "localization_source": after[1] if after else None,
    }


def _write(loaded: Iterable[tuple[TrialRecord, Maze]], tmp: Path, per: Episode) -> dict[str, int]:
    import pandas as pd
    import pyarrow as pa
    import pyarrow.parquet as pq

    rows: dict[str, list[Any]] = {k: [] for k in COLUMNS}
    tasks: dict[str, int] = {}
    episodes: list[dict[str, int | float | str | list[str]]] = []  # rows of the episodes table
    shape: tuple[int, int] = (0, 0)
    for record, maze in loaded:
        for group in episodes_of(record, maze, per):
            ep = len(episodes)
            images = [record.frame_bytes(s.frame) for s in group]
            shape = _encode_video(tmp / VIDEO_PATH.format(video_key=VIDEO_KEY, chunk_index=0, file_index=ep), images)
            start = len(rows["index"])
            for i, step in enumerate(group):
                task_index = tasks.setdefault(step.task, len(tasks))
                for key, value in (
                    ("observation.state", step.state),
                    ("action", int(step.action)),
                    ("language.messages", json.dumps(step.messages)),
                    ("frame_seq", step.frame.seq),
                    ("trial_id", int(record.trial_id)),
                    ("timestamp", i / FPS),
                    ("frame_index", i),
                    ("episode_index", ep),
                    ("index", start + i),
                    ("task_index", task_index),
                ):
                    rows[key].append(value)
            episodes.append(
                {
                    "episode_index": ep,
                    "tasks": list(dict.fromkeys(s.task for s in group)),
                    "length": len(group),
                    "data/chunk_index": 0,
                    "data/file_index": 0,
                    "dataset_from_index": start,
                    "dataset_to_index": start + len(group),
                    f"videos/{VIDEO_KEY}/chunk_index": 0,
                    f"videos/{VIDEO_KEY}/file_index": ep,
                    f"videos/{VIDEO_KEY}/from_timestamp": 0.0,
                    f"videos/{VIDEO_KEY}/to_timestamp": len(group) / FPS,
                    "meta/episodes/chunk_index": 0,
                    "meta/episodes/file_index": 0,
                    "trial_id": int(record.trial_id),
                    "annotation": json.dumps(_annotation(record)),
                }
            )
    if not episodes:
        raise ExportError("no episodes to write")
    n = len(rows["index"])
    arrow = {k: pa.type_for_alias(dtype) for k, dtype in COLUMNS.items()}
    arrow["observation.state"] = pa.list_(arrow["observation.state"], len(STATE_NAMES))
    table = pa.table({k: pa.array(rows[k], arrow[k]) for k in COLUMNS})
    (tmp / DATA_FILE).parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(table, tmp / DATA_FILE)
    (tmp / EPISODES_FILE).parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(pa.Table.from_pylist(episodes), tmp / EPISODES_FILE)
    pd.DataFrame({"task_index": list(tasks.values())}, index=pd.Index(list(tasks), name="task")).to_parquet(
        tmp / "meta/tasks.parquet"
    )
    height, width = shape
    features: dict[str, dict[str, object]] = {
        VIDEO_KEY: {
            "dtype": "video",
            "shape": [height, width, 3],
            "names": ["height", "width", "channels"],
            "info": {
                "video.height": height,
                "video.width": width,
                "video.codec": "h264",
                "video.pix_fmt": "yuv420p",
                "video.is_depth_map": False,
                "video.fps": FPS,
                "video.channels": 3,
                "has_audio": False,
            },
        },
    }
    for k, dtype in COLUMNS.items():
        dims, names = SHAPES.get(k, ([1], None))
        features[k] = {"dtype": dtype, "shape": dims, "names": names}
    info = {
        "codebase_version": CODEBASE_VERSION,
        "robot_type": "robotslang_rover",
        "total_episodes": len(episodes),
        "total_frames": n,
        "total_tasks": len(tasks),
        "chunks_size": 1000,
        "data_files_size_in_mb": 100,
        "video_files_size_in_mb": 500,
        "fps": FPS,
        "splits": {"train": f"0:{len(episodes)}"},
        "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
        "video_path": VIDEO_PATH,
        "features": features,
    }
    (tmp / "meta/info.json").write_text(json.dumps(info, indent=2))
    numeric = {k: np.array(rows[k]) for k, dtype in COLUMNS.items() if dtype != "string"}
    (tmp / "meta/stats.json").write_text(json.dumps({k: _stats(v) for k, v in numeric.items()}, indent=2))
    return {"episodes": len(episodes), "frames": n, "tasks": len(tasks)}

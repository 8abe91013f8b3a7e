"""One trial as an MCAP file that Foxglove opens: a channel per stream, the server's clock.

Every event of the log becomes exactly one message on its own topic (its `sequence` is the
event's `seq`): frames on `/driver/camera` and `/overhead/camera` (`foxglove.CompressedImage`),
chat on `/chat` (`foxglove.Log`, `name` = the speaker's role), moves on `/driver/cmd`, poses on
`/robot/pose/<source>` (`foxglove.PoseInFrame` in the `table` frame; source sim, tracker or
annotated), the Commander's estimates on `/commander/estimate` (`foxglove.PoseInFrame`) and
everything else (phases, connections, target claims) on `/trial/event`. Two topics are derived,
with `sequence` 0: `/maze/scene` (`foxglove.SceneUpdate`: walls and numbered targets, once) and
`/tf` (`foxglove.FrameTransform`: `table` -> `robot/<source>` at every pose). `log_time` is when
the server logged the event; `publish_time` is the camera's capture time for frames.

The Foxglove channels carry the published JSON schemas (`foxglove_schemas/`).
"""

from __future__ import annotations

import base64
import json
import math
from functools import cache
from pathlib import Path
from typing import Any

import cv2
from mcap.writer import Writer

from app.export.foxglove_scene import scene_update
from app.export.record import ExportError, TrialRecord
from sim.core.maze import FIXED_MAP, WALLS_MAP, Maze
from sim.trial import events as ev
from sim.trial.state import LoggedEvent
from sim.trial.vocabulary import PoseSource

PROFILE = ""  # plain JSON messages: no ROS profile
TABLE_FRAME = "table"
SCHEMA_DIR = Path(__file__).with_name("foxglove_schemas")
FOXGLOVE_SCHEMAS = (
    "foxglove.CompressedImage",
    "foxglove.Log",
    "foxglove.PoseInFrame",
    "foxglove.FrameTransform",
    "foxglove.SceneUpdate",
)


_ROBOTSLANG_SCHEMAS: dict[str, dict[str, Any]] = {
    "robotslang.DriverCommand": {
        "title": "robotslang.DriverCommand",
        "type": "object",
        "properties": {
            "stage": {"type": "string", "enum": ["requested", "executed"]},
            "move_id": {},
            "action": {"type": "string"},
            "outcome": {"type": ["string", "null"]},
            "collision": {"type": ["boolean", "null"]},
            "reason": {"type": ["string", "null"]},
        },
        "required": ["stage", "move_id", "action"],
    },
    "robotslang.TrialEvent": {
        "title": "robotslang.TrialEvent",
        "type": "object",
        "properties": {"seq": {"type": "integer"}, "kind": {"type": "string"}, "payload": {"type": "object"}},
        "required": ["seq", "kind", "payload"],
    },
}


@cache
def schemas() -> dict[str, dict[str, Any]]:
    """Schema name -> JSON schema: Foxglove's published ones and the platform's own two."""
    published = {name: json.loads((SCHEMA_DIR / f"{name}.json").read_text()) for name in FOXGLOVE_SCHEMAS}
    return {**published, **_ROBOTSLANG_SCHEMAS}


# topic -> schema; the order is the channel order in the file.
CHANNELS: dict[str, str] = {
    "/driver/camera": "foxglove.CompressedImage",
    "/overhead/camera": "foxglove.CompressedImage",
    "/chat": "foxglove.Log",
    "/driver/cmd": "robotslang.DriverCommand",
    **{f"/robot/pose/{s.value}": "foxglove.PoseInFrame" for s in PoseSource},
    "/commander/estimate": "foxglove.PoseInFrame",
    "/tf": "foxglove.FrameTransform",
    "/maze/scene": "foxglove.SceneUpdate",
    "/trial/event": "robotslang.TrialEvent",
}

# Topics written from other messages rather than from one event each (their `sequence` is 0).
DERIVED_TOPICS = ("/tf", "/maze/scene")

LOG_INFO = 2
_IMAGE_FORMATS = {"image/jpeg": "jpeg", "image/png": "png", "image/webp": "webp"}


def pose_source(record: TrialRecord, event: LoggedEvent) -> PoseSource:
    try:
        return PoseSource(event.payload.get("source", PoseSource.SIM))
    except ValueError:
        raise ExportError(
            f"trial {record.trial_id}: pose event {event.seq} has source "
            f"{event.payload.get('source')!r}; expected one of "
            f"{', '.join(s.value for s in PoseSource)}"
        ) from None


def topic_of(event: LoggedEvent) -> str:
    """The one channel an event is written to."""
    if event.is_(ev.FrameRecorded):
        source = event.payload.get("source", "driver")
        return "/overhead/camera" if source == "overhead" else "/driver/camera"
    if event.is_(ev.Chat):
        return "/chat"
    if event.is_(ev.MoveRequested, ev.MoveExecuted):
        return "/driver/cmd"
    if event.is_(ev.PoseSampled):
        return f"/robot/pose/{event.payload.get('source', 'sim')}"
    if event.is_(ev.Localized):
        return "/commander/estimate"
    return "/trial/event"


def write_mcap(record: TrialRecord, maze: Maze | None, out: str | Path) -> Path:
    """Write `record` to `out` (an .mcap file); returns its path. The maze's maps, where given,
    are attached in the benchmark's two PNG forms."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    events = sorted(record.events, key=lambda e: (e.t_ns, e.seq))
    # Read every frame and check every pose before opening the file, so a bad log leaves no
    # half-written MCAP.
    images = {e.seq: record.frame_bytes(e) for e in events if e.is_(ev.FrameRecorded)}
    sources = {e.seq: pose_source(record, e) for e in events if e.is_(ev.PoseSampled)}
    missing = [t for t in record.targets if maze is not None and t not in maze.objects]
    if missing:
        raise ExportError(f"trial {record.trial_id}: maze {record.maze} has no {', '.join(missing)}")
    tmp = out.with_name(out.name + ".part")
    with tmp.open("wb") as stream:
        writer = Writer(stream)
        writer.start(profile=PROFILE, library="robotslang")
        schema_ids = {
            name: writer.register_schema(name=name, encoding="jsonschema", data=json.dumps(schema).encode())
            for name, schema in schemas().items()
        }
        channel_ids = {
            topic: writer.register_channel(topic=topic, message_encoding="json", schema_id=schema_ids[schema])
            for topic, schema in CHANNELS.items()
        }

        def add(topic: str, message: dict[str, Any], log_ns: int, publish_ns: int, sequence: int) -> None:
            writer.add_message(
                channel_id=channel_ids[topic],
                log_time=log_ns,
                publish_time=publish_ns,
                sequence=sequence,
                data=json.dumps(message, separators=(",", ":")).encode(),
            )

        start_ns = events[0].t_ns if events else 0
        if maze is not None:
            add("/maze/scene", scene_update(maze, record.targets, _stamp(start_ns), TABLE_FRAME), start_ns, start_ns, 0)
        for event in events:
            message, publish_ns = _message(record, event, images.get(event.seq))
            add(topic_of(event), message, event.t_ns, publish_ns, event.seq)
            if event.is_(ev.PoseSampled):
                add("/tf", _transform(message, f"robot/{sources[event.seq].value}"), event.t_ns, event.t_ns, 0)
        writer.add_metadata("trial", _trial_metadata(record, maze))
        if record.localized_after is not None or record.tags:
            writer.add_metadata("annotation", _annotation_metadata(record))
        if maze is not None:
            for name, walls_only in ((FIXED_MAP, False), (WALLS_MAP, True)):
                ok, png = cv2.imencode(".png", maze.image(walls_only=walls_only))
                writer.add_attachment(
                    create_time=start_ns, log_time=start_ns, name=name, media_type="image/png", data=png.tobytes()
                )
        writer.finish()  # type: ignore[no-untyped-call]  # mcap's Writer.finish is not annotated
    tmp.replace(out)
    return out


def _trial_metadata(record: TrialRecord, maze: Maze | None) -> dict[str, str]:
    meta = {
        "trial_id": str(record.trial_id),
        "team": record.team,
        "maze": record.maze,
        "targets": ",".join(record.targets),
    }
    if maze is not None:
        meta["target_positions"] = json.dumps({t: maze.objects[t] for t in record.targets})
    meta.update({k: str(v) for k, v in record.info.items()})
    return meta


def _annotation_metadata(record: TrialRecord) -> dict[str, str]:
    """The annotated end of localization and the dialog's phenomena (message numbers from 1)."""
    meta = {"tags": json.dumps(record.tags)}
    if record.localized_after is not None:
        meta["localized_after_message"], meta["localization_source"] = map(str, record.localized_after)
    return meta


def _stamp(ns: int) -> dict[str, int]:
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def _message(record: TrialRecord, event: LoggedEvent, image: bytes | None) -> tuple[dict[str, Any], int]:
    p = event.payload
    if event.is_(ev.FrameRecorded):
        capture = int(p.get("capture_ns") or event.t_ns)
        fmt = _IMAGE_FORMATS.get(p.get("mime", "image/jpeg"))
        if fmt is None:
            raise ExportError(
                f"trial {record.trial_id}: frame {p.get('frame_id')} has image type "
                f"{p.get('mime')!r}; expected one of {', '.join(_IMAGE_FORMATS)}"
            )
        assert image is not None  # every frame event's image is read before the messages are written
        return {
            "timestamp": _stamp(capture),
            "frame_id": p.get("source", "driver"),
            "data": base64.b64encode(image).decode("ascii"),
            "format": fmt,
        }, capture
    if event.is_(ev.Chat):
        return {
            "timestamp": _stamp(event.t_ns),
            "level": LOG_INFO,
            "message": p.get("text", ""),
            "name": p.get("role", ""),
            "file": "",
            "line": 0,
        }, event.t_ns
    if event.is_(ev.MoveRequested, ev.MoveExecuted):
        fields = list(_ROBOTSLANG_SCHEMAS["robotslang.DriverCommand"]["properties"])[1:]  # after `stage`
        return {"stage": event.kind.removeprefix("move_"), **{k: p.get(k) for k in fields}}, event.t_ns
    if event.is_(ev.PoseSampled, ev.Localized):
        return _pose_in_frame(event.t_ns, float(p["x"]), float(p["y"]), p.get("heading")), event.t_ns
    return {"seq": event.seq, "kind": event.kind, "payload": p}, event.t_ns


def _pose_in_frame(t_ns: int, x: float, y: float, heading: float | None) -> dict[str, Any]:
    """A pose in the table frame; a heading the Commander left out is the identity rotation."""
    half = float(heading or 0.0) / 2
    return {
        "timestamp": _stamp(t_ns),
        "frame_id": TABLE_FRAME,
        "pose": {
            "position": {"x": x, "y": y, "z": 0.0},
            "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(half), "w": math.cos(half)},
        },
    }


def _transform(pose: dict[str, Any], child: str) -> dict[str, Any]:
    return {
        "timestamp": pose["timestamp"],
        "parent_frame_id": TABLE_FRAME,
        "child_frame_id": child,
        "translation": pose["pose"]["position"],
        "rotation": pose["pose"]["orientation"],
    }

"""One trial as an MCAP file that Foxglove opens: a channel per stream, the server's clock.

Every event of the log becomes exactly one message (its `sequence` is the event's `seq`):
frames on `/driver/camera` and `/overhead/camera` (`foxglove.CompressedImage`), chat on
`/chat` (`foxglove.Log`, `name` = the speaker's role), moves on `/driver/cmd`, poses on
`/robot/pose` (`foxglove.PoseInFrame` in the `table` frame) and everything else (phases,
connections, localization estimates, target claims) on `/trial/event`. `log_time` is when the
server logged the event; `publish_time` is the camera's capture time for frames.
"""

from __future__ import annotations

import base64
import json
import math
from pathlib import Path

import cv2
from mcap.writer import Writer

from app.export.record import ExportError, TrialRecord
from app.trial.state import LoggedEvent
from sim.maze import FIXED_MAP, WALLS_MAP, Maze

PROFILE = ""  # plain JSON messages: no ROS profile
TABLE_FRAME = "table"

_TIME = {
    "type": "object",
    "properties": {"sec": {"type": "integer", "minimum": 0},
                   "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}},
}
_VECTOR3 = {"type": "object", "properties": {a: {"type": "number"} for a in "xyz"}}
_QUATERNION = {"type": "object", "properties": {a: {"type": "number"} for a in "xyzw"}}

# The JSON schemas Foxglove recognises by name (github.com/foxglove/schemas, jsonschema/).
SCHEMAS: dict[str, dict] = {
    "foxglove.CompressedImage": {
        "title": "foxglove.CompressedImage", "type": "object",
        "properties": {"timestamp": _TIME, "frame_id": {"type": "string"},
                       "data": {"type": "string", "contentEncoding": "base64"},
                       "format": {"type": "string"}},
    },
    "foxglove.Log": {
        "title": "foxglove.Log", "type": "object",
        "properties": {"timestamp": _TIME,
                       "level": {"type": "integer", "enum": [0, 1, 2, 3, 4, 5]},
                       "message": {"type": "string"}, "name": {"type": "string"},
                       "file": {"type": "string"}, "line": {"type": "integer", "minimum": 0}},
    },
    "foxglove.PoseInFrame": {
        "title": "foxglove.PoseInFrame", "type": "object",
        "properties": {"timestamp": _TIME, "frame_id": {"type": "string"},
                       "pose": {"type": "object",
                                "properties": {"position": _VECTOR3, "orientation": _QUATERNION}}},
    },
    "robotslang.DriverCommand": {
        "title": "robotslang.DriverCommand", "type": "object",
        "properties": {"stage": {"type": "string", "enum": ["requested", "executed"]},
                       "move_id": {}, "action": {"type": "string"},
                       "outcome": {"type": ["string", "null"]},
                       "collision": {"type": ["boolean", "null"]},
                       "reason": {"type": ["string", "null"]}},
    },
    "robotslang.TrialEvent": {
        "title": "robotslang.TrialEvent", "type": "object",
        "properties": {"seq": {"type": "integer"}, "kind": {"type": "string"},
                       "payload": {"type": "object"}},
    },
}

# topic -> schema; the order is the channel order in the file.
CHANNELS: dict[str, str] = {
    "/driver/camera": "foxglove.CompressedImage",
    "/overhead/camera": "foxglove.CompressedImage",
    "/chat": "foxglove.Log",
    "/driver/cmd": "robotslang.DriverCommand",
    "/robot/pose": "foxglove.PoseInFrame",
    "/trial/event": "robotslang.TrialEvent",
}

LOG_INFO = 2
_IMAGE_FORMATS = {"image/jpeg": "jpeg", "image/png": "png", "image/webp": "webp"}


def topic_of(event: LoggedEvent) -> str:
    """The one channel an event is written to."""
    if event.kind == "frame":
        source = event.payload.get("source", "driver")
        return "/overhead/camera" if source == "overhead" else "/driver/camera"
    if event.kind == "chat":
        return "/chat"
    if event.kind in ("move_requested", "move_executed"):
        return "/driver/cmd"
    if event.kind == "pose":
        return "/robot/pose"
    return "/trial/event"


def write_mcap(record: TrialRecord, maze: Maze | None, out: str | Path) -> Path:
    """Write `record` to `out` (an .mcap file); returns its path. The maze's maps, where given,
    are attached in the benchmark's two PNG forms."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    events = sorted(record.events, key=lambda e: (e.t_ns, e.seq))
    # Read every frame before opening the file, so a missing image leaves no half-written MCAP.
    images = {e.seq: record.frame_bytes(e) for e in events if e.kind == "frame"}
    tmp = out.with_name(out.name + ".part")
    with tmp.open("wb") as stream:
        writer = Writer(stream)
        writer.start(profile=PROFILE, library="robotslang")
        schema_ids = {name: writer.register_schema(name=name, encoding="jsonschema",
                                                   data=json.dumps(schema).encode())
                      for name, schema in SCHEMAS.items()}
        channel_ids = {topic: writer.register_channel(topic=topic, message_encoding="json",
                                                      schema_id=schema_ids[schema])
                       for topic, schema in CHANNELS.items()}
        for event in events:
            message, publish_ns = _message(record, event, images.get(event.seq))
            writer.add_message(channel_id=channel_ids[topic_of(event)], log_time=event.t_ns,
                               publish_time=publish_ns, sequence=event.seq,
                               data=json.dumps(message, separators=(",", ":")).encode())
        writer.add_metadata("trial", _trial_metadata(record, maze))
        if maze is not None:
            created = events[0].t_ns if events else 0
            for name, walls_only in ((FIXED_MAP, False), (WALLS_MAP, True)):
                ok, png = cv2.imencode(".png", maze.image(walls_only=walls_only))
                writer.add_attachment(create_time=created, log_time=created, name=name,
                                      media_type="image/png", data=png.tobytes())
        writer.finish()
    tmp.replace(out)
    return out


def _trial_metadata(record: TrialRecord, maze: Maze | None) -> dict[str, str]:
    meta = {"trial_id": str(record.trial_id), "team": record.team, "maze": record.maze,
            "targets": ",".join(record.targets)}
    if maze is not None:
        meta["target_positions"] = json.dumps({t: maze.objects[t] for t in record.targets})
    meta.update({k: str(v) for k, v in record.info.items()})
    return meta


def _stamp(ns: int) -> dict[str, int]:
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def _message(record: TrialRecord, event: LoggedEvent, image: bytes | None) -> tuple[dict, int]:
    p = event.payload
    if event.kind == "frame":
        capture = int(p.get("capture_ns") or event.t_ns)
        fmt = _IMAGE_FORMATS.get(p.get("mime", "image/jpeg"))
        if fmt is None:
            raise ExportError(f"trial {record.trial_id}: frame {p.get('frame_id')} has image type "
                              f"{p.get('mime')!r}; expected one of {', '.join(_IMAGE_FORMATS)}")
        return {"timestamp": _stamp(capture), "frame_id": p.get("source", "driver"),
                "data": base64.b64encode(image).decode("ascii"), "format": fmt}, capture
    if event.kind == "chat":
        return {"timestamp": _stamp(event.t_ns), "level": LOG_INFO, "message": p.get("text", ""),
                "name": p.get("role", ""), "file": "", "line": 0}, event.t_ns
    if event.kind in ("move_requested", "move_executed"):
        return {"stage": event.kind.removeprefix("move_"), "move_id": p.get("move_id"),
                "action": p.get("action"), "outcome": p.get("outcome"),
                "collision": p.get("collision"), "reason": p.get("reason")}, event.t_ns
    if event.kind == "pose":
        half = float(p.get("heading") or 0.0) / 2
        return {"timestamp": _stamp(event.t_ns), "frame_id": TABLE_FRAME,
                "pose": {"position": {"x": float(p["x"]), "y": float(p["y"]), "z": 0.0},
                         "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(half),
                                         "w": math.cos(half)}}}, event.t_ns
    return {"seq": event.seq, "kind": event.kind, "payload": p}, event.t_ns

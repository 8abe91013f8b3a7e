"""The Foxglove messages the MCAP export writes, as TypedDicts of their published JSON schemas
(`foxglove_schemas/`), and the platform's own two."""

from __future__ import annotations

from typing import TypedDict


class Time(TypedDict):
    sec: int
    nsec: int


class Vector3(TypedDict):
    x: float
    y: float
    z: float


class Quaternion(TypedDict):
    x: float
    y: float
    z: float
    w: float


class Pose(TypedDict):
    position: Vector3
    orientation: Quaternion


class Color(TypedDict):
    r: float
    g: float
    b: float
    a: float


class CubePrimitive(TypedDict):
    pose: Pose
    size: Vector3
    color: Color


class CylinderPrimitive(CubePrimitive):
    bottom_scale: float
    top_scale: float


class TextPrimitive(TypedDict):
    pose: Pose
    billboard: bool
    font_size: float
    scale_invariant: bool
    color: Color
    text: str


class SceneEntity(TypedDict):
    timestamp: Time
    frame_id: str
    id: str
    lifetime: Time
    frame_locked: bool
    metadata: list[dict[str, str]]
    arrows: list[object]
    cubes: list[CubePrimitive]
    spheres: list[object]
    cylinders: list[CylinderPrimitive]
    lines: list[object]
    triangles: list[object]
    texts: list[TextPrimitive]
    models: list[object]


class SceneUpdate(TypedDict):
    deletions: list[object]
    entities: list[SceneEntity]


class CompressedImage(TypedDict):
    timestamp: Time
    frame_id: str
    data: str  # base64
    format: str


class Log(TypedDict):
    timestamp: Time
    level: int
    message: str
    name: str
    file: str
    line: int


class PoseInFrame(TypedDict):
    timestamp: Time
    frame_id: str
    pose: Pose


class FrameTransform(TypedDict):
    timestamp: Time
    parent_frame_id: str
    child_frame_id: str
    translation: Vector3
    rotation: Quaternion


class DriverCommand(TypedDict):
    """robotslang.DriverCommand: a move requested or executed."""

    stage: str  # "requested" or "executed"
    move_id: object
    action: str | None
    outcome: str | None
    collision: bool | None
    reason: str | None


class TrialEvent(TypedDict):
    """robotslang.TrialEvent: any other event of the log, as logged."""

    seq: int
    kind: str
    payload: dict[str, object]


Message = CompressedImage | Log | PoseInFrame | FrameTransform | SceneUpdate | DriverCommand | TrialEvent

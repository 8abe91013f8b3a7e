"""The wire protocol between the rover and the server (docs/protocol.md), shared by both ends.

One websocket. Binary messages are camera frames: a fixed header then the JPEG bytes. Text
messages are JSON objects with a `type`. This module only encodes and checks messages; it
knows nothing about sockets, motors or trials.
"""

from __future__ import annotations

import json
import struct
from dataclasses import dataclass
from enum import Enum

PROTOCOL_VERSION = 1

# Frame header: magic, sequence number, capture time (sender's monotonic clock, ns),
# width, height. Network byte order; 20 bytes.
FRAME_MAGIC = b"RSF1"
FRAME_HEADER = struct.Struct("!4sIQHH")


class Move(str, Enum):
    """The Driver's discrete moves (0.07 m forward, or a 45 degree turn): the one move vocabulary,
    from this wire protocol to the server, the simulator and the learners."""

    FORWARD = "forward"
    LEFT = "left"
    RIGHT = "right"

    def __str__(self) -> str:  # the wire's string (a StrEnum's, which Python 3.9 lacks)
        return self.value


ROLES = ("driver", "overhead")

MAX_TEXT_BYTES = 64 * 1024
DEFAULT_MAX_FRAME_BYTES = 2 * 1024 * 1024

# Closing codes the server uses so the rover can tell "try again" from "give up".
CLOSE_REFUSED = 4401
CLOSE_REPLACED = 4409


class ProtocolError(ValueError):
    """A message that breaks the protocol; the text says which part and why."""


@dataclass(frozen=True)
class FrameHeader:
    seq: int
    capture_ns: int
    width: int
    height: int


def pack_frame(seq: int, capture_ns: int, width: int, height: int, jpeg: bytes) -> bytes:
    return FRAME_HEADER.pack(FRAME_MAGIC, seq & 0xFFFFFFFF, capture_ns, width, height) + jpeg


def unpack_frame(data: bytes, max_bytes: int = DEFAULT_MAX_FRAME_BYTES) -> tuple[FrameHeader, bytes]:
    """Split a binary frame message into its header and JPEG, or raise ProtocolError."""
    if len(data) > max_bytes:
        raise ProtocolError(f"frame message is {len(data)} bytes; the limit is {max_bytes}")
    if len(data) <= FRAME_HEADER.size:
        raise ProtocolError(
            f"frame message is {len(data)} bytes, too short for the {FRAME_HEADER.size}-byte header and a JPEG"
        )
    magic, seq, capture_ns, width, height = FRAME_HEADER.unpack_from(data)
    if magic != FRAME_MAGIC:
        raise ProtocolError(f"frame header starts with {magic!r}, expected {FRAME_MAGIC!r}")
    if width == 0 or height == 0:
        raise ProtocolError(f"frame header gives size {width}x{height}; both must be positive")
    jpeg = data[FRAME_HEADER.size :]
    if jpeg[:2] != b"\xff\xd8":
        raise ProtocolError("frame payload is not a JPEG (missing the FF D8 start marker)")
    return FrameHeader(seq, capture_ns, width, height), bytes(jpeg)


def encode(message: dict) -> str:
    return json.dumps(message, separators=(",", ":"))


def decode(text: str | bytes, expected: tuple[str, ...] | None = None) -> dict:
    """Parse one JSON message and check it has a known `type`, or raise ProtocolError."""
    if len(text) > MAX_TEXT_BYTES:
        raise ProtocolError(f"text message is {len(text)} bytes; the limit is {MAX_TEXT_BYTES}")
    try:
        message = json.loads(text)
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ProtocolError(f"text message is not JSON: {exc}") from None
    if not isinstance(message, dict) or not isinstance(message.get("type"), str):
        raise ProtocolError("text message must be a JSON object with a string field 'type'")
    if expected is not None and message["type"] not in expected:
        raise ProtocolError(f"unknown message type {message['type']!r}; expected one of {', '.join(expected)}")
    return message


# Messages the server sends to the rover, and the rover to the server.
SERVER_TYPES = ("welcome", "ping", "move", "stop", "error")
ROBOT_TYPES = ("hello", "pong", "ack", "error")

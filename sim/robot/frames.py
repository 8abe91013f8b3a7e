"""Camera frames as they travel: JPEG bytes. One decoder, one rule, for every camera."""

from __future__ import annotations

import cv2
import numpy as np

JPEG_SOI = b"\xff\xd8"


class FrameError(ValueError):
    """Frame bytes that are not a decodable JPEG image."""


def decode_jpeg(data: bytes | bytearray | memoryview) -> np.ndarray:
    """JPEG bytes -> BGR image; `FrameError`, naming what came instead, for anything else (a
    payload that merely starts like a JPEG must decode too)."""
    if not isinstance(data, (bytes, bytearray, memoryview)) or bytes(data[:2]) != JPEG_SOI:
        head = bytes(data[:4]).hex(" ") if isinstance(data, (bytes, bytearray, memoryview)) else type(data).__name__
        raise FrameError(f"frame is not a JPEG (starts with {head or 'nothing'}; a JPEG starts ff d8)")
    image = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_COLOR)
    if image is None:
        raise FrameError(f"frame of {len(data)} bytes starts like a JPEG but does not decode")
    return np.asarray(image)

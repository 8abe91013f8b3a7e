"""Camera sources and the grabber thread that keeps only the newest encoded frame.

A source returns BGR images: a USB webcam or a video file through OpenCV, the Pi camera through
picamera2, or a synthetic pattern for development and tests. The grabber captures at the set
rate, stamps each image with the monotonic clock as it is read, JPEG-encodes it and overwrites a
single slot, so a slow link only ever sends the newest frame and never builds a backlog.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np


class CameraError(RuntimeError):
    """The camera could not be opened or stopped delivering images; the text says which."""


@dataclass(frozen=True)
class CameraSettings:
    width: int = 640
    height: int = 480
    fps: float = 15.0
    quality: int = 80

    def __post_init__(self) -> None:
        if not (16 <= self.width <= 4096 and 16 <= self.height <= 4096):
            raise CameraError(f"frame size must be 16..4096 pixels a side, got {self.width}x{self.height}")
        if not 0 < self.fps <= 120:
            raise CameraError(f"frame rate must be in (0, 120] frames per second, got {self.fps}")
        if not 1 <= self.quality <= 100:
            raise CameraError(f"JPEG quality must be 1..100, got {self.quality}")

    def info(self, source: str) -> dict:
        """The hello's `camera`: where the frames come from, and how they are taken."""
        return {"source": source, "width": self.width, "height": self.height, "fps": self.fps, "quality": self.quality}


class SyntheticCamera:
    """A moving colour pattern with the frame number written on it: no hardware needed.

    Fine-grained texture on the gradient makes its JPEGs about as large as a webcam's."""

    def __init__(self, width: int, height: int) -> None:
        x = np.linspace(0, 255, width, dtype=np.float32)
        y = np.linspace(0, 255, height, dtype=np.float32)[:, None]
        base = np.dstack(
            [
                np.broadcast_to(x, (height, width)),
                np.broadcast_to(y, (height, width)),
                np.full((height, width), 128, np.float32),
            ]
        )
        texture = np.random.default_rng(0).normal(0, 5, (height, width, 1)).astype(np.float32)
        self._base = np.clip(base + texture, 0, 255).astype(np.uint8)
        self._count = 0

    def read(self) -> np.ndarray:
        self._count += 1
        image = np.roll(self._base, 4 * self._count, axis=1)
        cv2.putText(image, f"#{self._count}", (12, 40), cv2.FONT_HERSHEY_SIMPLEX, 1.2, (255, 255, 255), 2, cv2.LINE_AA)
        return image

    def close(self) -> None:
        pass


class OpenCVCamera:
    """A USB webcam by index, or a video file (played in a loop)."""

    def __init__(self, source: int | str, settings: CameraSettings) -> None:
        self._source = source
        self._capture = cv2.VideoCapture(source)
        if not self._capture.isOpened():
            raise CameraError(f"cannot open camera {source!r}")
        self._is_file = isinstance(source, str)
        if not self._is_file:
            self._capture.set(cv2.CAP_PROP_FRAME_WIDTH, settings.width)
            self._capture.set(cv2.CAP_PROP_FRAME_HEIGHT, settings.height)
            self._capture.set(cv2.CAP_PROP_FPS, settings.fps)
            # Keep the driver's own queue short so a read returns a fresh image.
            self._capture.set(cv2.CAP_PROP_BUFFERSIZE, 1)

    def read(self) -> np.ndarray:
        ok, image = self._capture.read()
        if not ok and self._is_file:
            self._capture.set(cv2.CAP_PROP_POS_FRAMES, 0)
            ok, image = self._capture.read()
        if not ok:
            raise CameraError(f"camera {self._source!r} returned no image")
        return image

    def close(self) -> None:
        self._capture.release()


class PiCamera:
    """The Raspberry Pi camera module through picamera2."""

    def __init__(self, settings: CameraSettings) -> None:
        try:
            from picamera2 import Picamera2
        except ImportError:
            raise CameraError(
                "--camera picamera needs picamera2 (`sudo apt install python3-picamera2` on Raspberry Pi OS)"
            ) from None
        self._camera = Picamera2()
        # picamera2's "RGB888" is laid out B, G, R in memory: what OpenCV expects.
        config = self._camera.create_video_configuration(
            main={"size": (settings.width, settings.height), "format": "RGB888"}
        )
        self._camera.configure(config)
        self._camera.start()

    def read(self) -> np.ndarray:
        return self._camera.capture_array()

    def close(self) -> None:
        self._camera.stop()
        self._camera.close()


def open_camera(spec: str, settings: CameraSettings):
    """`0`, `1`, ... a webcam; `picamera`; `synthetic`; anything else a video file path."""
    if spec == "synthetic":
        return SyntheticCamera(settings.width, settings.height)
    if spec == "picamera":
        return PiCamera(settings)
    if spec.isdigit():
        return OpenCVCamera(int(spec), settings)
    if not Path(spec).is_file():
        raise CameraError(f"--camera {spec!r} is not a camera index, 'picamera', 'synthetic' or an existing video file")
    return OpenCVCamera(spec, settings)


@dataclass(frozen=True)
class EncodedFrame:
    seq: int
    capture_ns: int  # time.monotonic_ns() when the image was exposed (or read, see FrameGrabber._read)
    width: int
    height: int
    jpeg: bytes


class FrameGrabber:
    """Captures and encodes in its own thread; `latest()` is the newest frame or None.

    `on_frame` is called from the grabber thread after each new frame (to wake a sender)."""

    def __init__(self, camera, settings: CameraSettings) -> None:
        self._camera = camera
        self._settings = settings
        self._on_frame = None
        self._latest: EncodedFrame | None = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self.error: Exception | None = None
        self._thread = threading.Thread(target=self._run, name="frame-grabber", daemon=True)

    def start(self, on_frame=None) -> None:
        self._on_frame = on_frame
        self._thread.start()

    def latest(self) -> EncodedFrame | None:
        with self._lock:
            return self._latest

    def _run(self) -> None:
        s = self._settings
        period_ns = int(1e9 / s.fps)
        params = [cv2.IMWRITE_JPEG_QUALITY, s.quality]
        next_ns = time.monotonic_ns()
        seq = 0
        try:
            while not self._stop.is_set():
                image, capture_ns = self._read()
                if image.shape[1] != s.width or image.shape[0] != s.height:
                    image = cv2.resize(image, (s.width, s.height), interpolation=cv2.INTER_AREA)
                ok, jpeg = cv2.imencode(".jpg", image, params)
                if not ok:
                    raise CameraError("JPEG encoding failed")
                seq += 1
                frame = EncodedFrame(seq, capture_ns, s.width, s.height, jpeg.tobytes())
                with self._lock:
                    self._latest = frame
                if self._on_frame is not None:
                    self._on_frame()
                next_ns += period_ns
                wait_ns = next_ns - time.monotonic_ns()
                if wait_ns > 0:
                    self._stop.wait(wait_ns / 1e9)
                else:  # fell behind (slow camera): do not try to catch up with a burst
                    next_ns = time.monotonic_ns()
        except Exception as exc:  # reported to the client, which stops
            self.error = exc
            if self._on_frame is not None:
                self._on_frame()

    def _read(self):
        """An image and when it was exposed: the source's own time where it knows it
        (`read_stamped() -> (image, monotonic ns)`), else the moment `read()` returned."""
        stamped = getattr(self._camera, "read_stamped", None)
        if stamped is not None:
            return stamped()
        return self._camera.read(), time.monotonic_ns()

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2)
        self._camera.close()

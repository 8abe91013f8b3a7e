"""Camera sources and the grabber: JPEGs at the set size, capture times, newest frame only."""

import time

import cv2
import numpy as np
import pytest

from robot_client.camera import CameraError, CameraSettings, FrameGrabber, SyntheticCamera, open_camera


def test_grabber_encodes_jpegs_at_the_set_size_and_quality():
    grabber = FrameGrabber(SyntheticCamera(320, 240), CameraSettings(160, 120, fps=30, quality=50))
    grabber.start()
    try:
        deadline = time.monotonic() + 5
        while grabber.latest() is None and time.monotonic() < deadline:
            time.sleep(0.01)
        frame = grabber.latest()
    finally:
        grabber.stop()
    image = cv2.imdecode(np.frombuffer(frame.jpeg, np.uint8), cv2.IMREAD_COLOR)
    assert image.shape == (120, 160, 3) and (frame.width, frame.height) == (160, 120)


def test_a_slow_reader_gets_the_newest_frame_not_a_backlog():
    grabber = FrameGrabber(SyntheticCamera(160, 120), CameraSettings(160, 120, fps=30))
    grabber.start()
    try:
        time.sleep(0.2)
        first = grabber.latest()
        time.sleep(0.5)  # a link too slow to take every frame
        read_at = time.monotonic_ns()
        second = grabber.latest()
    finally:
        grabber.stop()
    assert second.seq - first.seq >= 10  # frames in between were dropped, not queued
    # What is sent is fresh: a backlog's next frame would be about 0.5 s old; 0.3 s leaves room for
    # a loaded machine to schedule the grabber late (two CI runs at once gave 176 ms).
    assert read_at - second.capture_ns < 300e6
    assert second.capture_ns > first.capture_ns


class SlowExposedCamera(SyntheticCamera):
    """A source that knows when its image was exposed, and takes a while to deliver it."""

    def __init__(self) -> None:
        super().__init__(160, 120)
        self.exposed: list[int] = []

    def read_stamped(self):
        self.exposed.append(time.monotonic_ns())
        time.sleep(0.05)
        return self.read(), self.exposed[-1]


def test_a_source_that_stamps_its_own_exposure_keeps_that_time():
    camera = SlowExposedCamera()
    grabber = FrameGrabber(camera, CameraSettings(160, 120, fps=10))
    grabber.start()
    try:
        deadline = time.monotonic() + 5
        while (grabber.latest() is None or grabber.latest().seq < 2) and time.monotonic() < deadline:
            time.sleep(0.01)
        frame = grabber.latest()
    finally:
        grabber.stop()
    assert frame.capture_ns == camera.exposed[frame.seq - 1]


def test_camera_settings_and_sources_name_what_is_wrong(tmp_path):
    with pytest.raises(CameraError, match="JPEG quality must be 1..100, got 0"):
        CameraSettings(quality=0)
    with pytest.raises(CameraError, match="frame rate"):
        CameraSettings(fps=0)
    with pytest.raises(CameraError, match="frame size"):
        CameraSettings(width=8)
    with pytest.raises(CameraError, match="not a camera index, 'picamera', 'synthetic' or an existing video file"):
        open_camera(str(tmp_path / "missing.mp4"), CameraSettings())
    broken = tmp_path / "broken.mp4"
    broken.write_bytes(b"not a video")
    with pytest.raises(CameraError, match="cannot open camera"):
        open_camera(str(broken), CameraSettings())

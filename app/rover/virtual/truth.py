"""The true continuous pose of a software rover, as a side file only a test harness reads.

JSON lines, one object each: `t_ns` (time.monotonic_ns() of the rover's machine: the clock of
the frames' `capture_ns`), `x`, `y` (metres), `theta` (radians, [0, 2 pi)), `move_id` (the
number of pulses the rover has started, 0 before the first), `action` (of that pulse, null
before the first), `moving` (a pulse is running), `collision` (the body touched something
during that pulse). A line is written when the rover starts, when each pulse starts and ends,
and every `SAMPLE_S` while it runs. The server never sees this file: no seat or trial can.
"""

from __future__ import annotations

import json
import os
import threading
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TextIO

SAMPLE_S = 0.01


@dataclass(frozen=True)
class TruthSample:
    t_ns: int
    x: float
    y: float
    theta: float
    move_id: int
    action: str | None
    moving: bool
    collision: bool

    @classmethod
    def from_json(cls, line: str) -> TruthSample:
        return cls(**json.loads(line))


class TruthLog:
    """Appends samples to the side file (a new file each time the rover starts); thread-safe."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        # A new file, not the old one truncated: a follower holding the old one open sees
        # another inode, however far the new one has grown by its next look.
        self.path.unlink(missing_ok=True)
        self._file = open(self.path, "w", buffering=1)  # noqa: SIM115  (held open until close())
        self._lock = threading.Lock()

    def write(self, sample: TruthSample) -> None:
        with self._lock:
            if not self._file.closed:
                # One write per line, line-buffered: a reader never sees half a line but the last.
                self._file.write(json.dumps(asdict(sample), separators=(",", ":")) + "\n")

    def close(self) -> None:
        with self._lock:
            self._file.close()


def read_truth(path: Path) -> list[TruthSample]:
    """Every complete sample in the file, in order (a line still being written is left out)."""
    text = Path(path).read_text()
    return [TruthSample.from_json(line) for line in text.splitlines(keepends=True) if line.endswith("\n")]


class TruthFollower:
    """The newest sample of a side file that another process is writing (None until there is one).

    Follows the file across a restart of its writer, which replaces it."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._file: TextIO | None = None
        self._inode: int | None = None
        self._partial = ""
        self.latest: TruthSample | None = None

    def poll(self) -> TruthSample | None:
        try:
            stat = os.stat(self.path)
        except FileNotFoundError:
            return self.latest
        if self._file is None or stat.st_ino != self._inode or stat.st_size < self._file.tell():
            if self._file is not None:
                self._file.close()
            self._file, self._inode, self._partial = open(self.path), stat.st_ino, ""  # noqa: SIM115  (followed across polls)
            self.latest = None
        chunk = self._partial + self._file.read()
        lines = chunk.split("\n")
        self._partial = lines.pop()  # "" after a complete line
        for line in reversed(lines):
            if line.strip():
                self.latest = TruthSample.from_json(line)
                break
        return self.latest

    def close(self) -> None:
        if self._file is not None:
            self._file.close()

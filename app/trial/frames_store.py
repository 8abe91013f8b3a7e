"""`FrameStore`: the trials' camera images on disk, one file each under `frames_dir`, found
again by the `frame` row their event committed (`{trial}/{capture_ns}-{source}.jpg`)."""

from __future__ import annotations

from pathlib import Path

from sqlalchemy import select
from sqlalchemy.orm import Session, sessionmaker

from app.db.models import Frame
from app.trial.log import EventLog
from sim.trial.vocabulary import FrameSource


class FrameStore:
    def __init__(self, frames_dir: Path, db: sessionmaker[Session], log: EventLog) -> None:
        self.frames_dir, self._db, self._log = frames_dir, db, log
        self._dirs: set[Path] = set()  # the folders made already (one per trial)

    @staticmethod
    def name(trial_id: int, capture_ns: int, source: FrameSource) -> str:
        """The file of one image, relative to `frames_dir` (the `path` its event records)."""
        return f"{trial_id}/{capture_ns}-{source}.jpg"

    def write(self, rel: str, jpeg: bytes) -> None:
        """Blocking: call it off the event loop where a slow disk must not delay other trials."""
        path = self.frames_dir / rel
        if path.parent not in self._dirs:
            path.parent.mkdir(parents=True, exist_ok=True)
            self._dirs.add(path.parent)
        path.write_bytes(jpeg)

    def read(self, trial_id: int, frame_id: int) -> bytes | None:
        """The image of a trial's frame event; None where there is none or its file is gone."""
        self._log.flush()  # the frame may be in this turn's batch
        with self._db() as db:
            rel = db.scalar(select(Frame.path).where(Frame.trial_id == trial_id, Frame.seq == frame_id))
        if rel is None:
            return None
        try:
            return (self.frames_dir / rel).read_bytes()
        except OSError:
            return None

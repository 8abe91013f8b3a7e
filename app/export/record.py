"""`TrialRecord`: one trial as the exports read it, the event log and where its frames are.

Exports are pure reads of the log; this is the only shape they need, so that MCAP and NDH
writers can be tested on events alone and the database adapter (`app.export.source`) stays
small.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from sim.trial.state import LoggedEvent


class ExportError(RuntimeError):
    """A trial that cannot be exported; the message names the trial and what is missing."""


@dataclass(frozen=True)
class TrialRecord:
    trial_id: str
    team: str
    maze: str
    targets: tuple[str, ...]
    events: tuple[LoggedEvent, ...]
    frames_root: Path | None  # frame payload `path`s are relative to this folder (None: no frames)
    info: dict[str, str] = field(default_factory=dict)  # anything else worth keeping as metadata
    # The annotated end of localization: after this many messages, and where that comes from
    # ("annotation" or "adjudicated", app.annotation); None: the Commander's first estimate ends it.
    localized_after: tuple[int, str] | None = None
    tags: dict[str, list[int]] = field(default_factory=dict)  # dialog phenomena -> message numbers

    def frame_bytes(self, event: LoggedEvent) -> bytes:
        """The encoded image a `frame` event points at."""
        rel = event.payload.get("path")
        if not rel:
            raise ExportError(f"trial {self.trial_id}: frame event {event.seq} has no file path")
        if not Path(rel).is_absolute() and self.frames_root is None:
            raise ExportError(f"trial {self.trial_id}: frame event {event.seq} but no frame folder given")
        path = Path(rel) if Path(rel).is_absolute() else self.frames_root / rel
        try:
            return path.read_bytes()
        except OSError as err:
            raise ExportError(
                f"trial {self.trial_id}: frame {event.payload.get('frame_id')} "
                f"(event {event.seq}) cannot be read from {path}: {err.strerror}"
            ) from None

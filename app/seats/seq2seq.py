"""`agent:seq2seq`: the learned NDH Driver (`models/driver.py`) in the Driver's seat.

The app imports models/, never the reverse; torch is loaded only when this agent is checked
(to offer it) or seated. Its checkpoint is ROBOTSLANG_SEQ2SEQ_CHECKPOINT where set, else the
one shipped in the package (`models.shipped`).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from app.seats.base import Seating

if TYPE_CHECKING:
    from app.seats.registry import AgentParts
    from models.driver import Seq2SeqDriver

NO_CHECKPOINT = (
    "agent:seq2seq needs a checkpoint: this install ships none; set ROBOTSLANG_SEQ2SEQ_CHECKPOINT "
    "to a file written by `robotslang train ndh` (e.g. RUN/best.pt)"
)


def seq2seq_checkpoint(parts: AgentParts) -> Path | None:
    """The setting where given, else the package's shipped Driver (None where it has none)."""
    if parts.settings.seq2seq_checkpoint is not None:
        return parts.settings.seq2seq_checkpoint
    from models.shipped import default_checkpoint

    return default_checkpoint()


def seq2seq_check(parts: AgentParts) -> str | None:
    """Why the checkpoint cannot be seated, or None; loaded once per version of the file."""
    checkpoint = seq2seq_checkpoint(parts)
    if checkpoint is None:
        return NO_CHECKPOINT
    try:
        stat = checkpoint.stat()
    except OSError as err:
        return f"agent:seq2seq: checkpoint {checkpoint}: {err.strerror or err}"
    key = ("seq2seq", str(checkpoint), stat.st_mtime_ns, stat.st_size)
    if key not in parts.agent_checks:
        try:
            from models.train import load_agent

            load_agent(checkpoint)
            parts.agent_checks[key] = None
        except Exception as err:  # any failure to load is the reason it is not offered
            parts.agent_checks[key] = f"agent:seq2seq cannot load checkpoint {checkpoint}: {err}"
    return parts.agent_checks[key]


def seq2seq_driver(parts: AgentParts, seating: Seating) -> Seq2SeqDriver:
    checkpoint = seq2seq_checkpoint(parts)
    if checkpoint is None:
        raise LookupError(NO_CHECKPOINT)
    from models.driver import Seq2SeqDriver

    return Seq2SeqDriver(checkpoint)

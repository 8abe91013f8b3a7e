"""`agent:seq2seq`: the learned NDH Driver (`models/driver.py`) in the Driver's seat.

The app imports models/, never the reverse; torch is loaded only when a trial seats this agent.
"""

from __future__ import annotations

from typing import Any

from app.drivers.registry import register_driver
from app.services import Services


def seq2seq_driver(info: dict[str, Any], services: Services):
    checkpoint = services.settings.seq2seq_checkpoint
    if checkpoint is None:
        raise LookupError("agent:seq2seq needs a checkpoint: set ROBOTSLANG_SEQ2SEQ_CHECKPOINT to a file "
                          "written by `robotslang train ndh` (e.g. RUN/best.pt)")
    from models.driver import Seq2SeqDriver

    mazes = services.mazes  # the server's, so the maze and its graph are not loaded again
    return Seq2SeqDriver(checkpoint, lambda name: (mazes.load(name), mazes.graph(name)))


register_driver("seq2seq", seq2seq_driver)

"""A trial's dialog as annotators see it: messages numbered from 1 in the log's order, and the
aids placed between them (the Commander's estimates, with the true pose when each was made)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from sim.trial import events as ev
from sim.trial.state import LoggedEvent


@dataclass(frozen=True)
class Message:
    number: int
    role: str
    text: str
    seq: int
    t_s: float  # seconds since the trial's first event


@dataclass(frozen=True)
class Estimate:
    after_message: int  # how many messages were sent before it
    x: float
    y: float
    true_x: float | None
    true_y: float | None

    @property
    def error_m(self) -> float | None:
        if self.true_x is None or self.true_y is None:
            return None
        return math.dist((self.x, self.y), (self.true_x, self.true_y))


def messages(events: Sequence[LoggedEvent]) -> list[Message]:
    t0 = events[0].t_ns if events else 0
    chats = [e for e in sorted(events, key=lambda e: e.seq) if e.is_(ev.Chat)]
    return [
        Message(n, str(e.payload["role"]), str(e.payload["text"]), e.seq, (e.t_ns - t0) / 1e9)
        for n, e in enumerate(chats, start=1)
    ]


def estimates(events: Sequence[LoggedEvent]) -> list[Estimate]:
    out = []
    said = 0
    truth: tuple[float, float] | None = None
    for e in sorted(events, key=lambda e: e.seq):
        if e.is_(ev.Chat):
            said += 1
        elif e.is_(ev.PoseSampled):
            truth = (float(e.payload["x"]), float(e.payload["y"]))
        elif e.is_(ev.Localized):
            out.append(Estimate(said, float(e.payload["x"]), float(e.payload["y"]), *(truth or (None, None))))
    return out

"""`TrialState`: everything about a trial, rebuilt from its events alone.

`fold(events)` is pure: the same events always give the same state, so a restarted server
resumes a trial from the database, and the leaderboard and exports read the same truth.
The trial clock runs only while localizing or navigating and nothing pauses it.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

PHASES = ("waiting", "localizing", "navigating", "finished", "aborted")
RUNNING_PHASES = ("localizing", "navigating")
PARTICIPANT_ROLES = ("commander", "driver")


@dataclass(frozen=True)
class LoggedEvent:
    seq: int
    kind: str
    t_ns: int
    payload: dict[str, Any]


@dataclass
class TrialState:
    maze: str = ""
    targets: list[str] = field(default_factory=list)
    backend: str = "sim"
    driver: str = "human"
    phase: str = "waiting"
    target_index: int = 0
    connected: set[str] = field(default_factory=set)
    pause_reasons: set[str] = field(default_factory=set)
    active_ns: int = 0  # clock time while running, up to `last_t_ns`
    last_t_ns: int | None = None
    started_ns: int | None = None
    moves: int = 0  # executed moves (ok or collision); refused ones do not count
    collisions: int = 0
    last_frame_id: int | None = None
    pending_claim: dict[str, Any] | None = None
    pose: tuple[float, float, float] | None = None  # last sampled true pose (x, y, theta)
    localization: dict[str, Any] | None = None
    confirmed: list[dict[str, Any]] = field(default_factory=list)
    finished_active_ns: int | None = None  # active time at the last confirmation
    last_seq: int = 0

    # -- derived ------------------------------------------------------------------
    @property
    def running(self) -> bool:
        return self.phase in RUNNING_PHASES and not self.pause_reasons

    @property
    def seats_needed(self) -> tuple[str, ...]:
        """The seats a trial waits for before it starts: both participants, and the rover when
        one is in the robot seat (a trial cannot start on a robot that is not connected)."""
        return PARTICIPANT_ROLES + (("robot",) if self.backend.startswith("robot:") else ())

    @property
    def waiting_for(self) -> list[str]:
        """The seats still missing while the trial waits to start."""
        if self.phase != "waiting":
            return []
        return [role for role in self.seats_needed if role not in self.connected]

    @property
    def over(self) -> bool:
        return self.phase in ("finished", "aborted")

    @property
    def current_target(self) -> str | None:
        if self.phase in RUNNING_PHASES and self.target_index < len(self.targets):
            return self.targets[self.target_index]
        return None

    def active_s(self, now_ns: int | None = None) -> float:
        """Seconds on the trial clock, at `now_ns` when the clock is running."""
        extra = 0
        if self.running and now_ns is not None and self.last_t_ns is not None:
            extra = max(0, now_ns - self.last_t_ns)
        return (self.active_ns + extra) / 1e9

    def score(self, move_penalty_s: float) -> float | None:
        """Time from start to the last target confirmed plus a penalty per move; None until finished."""
        if self.phase != "finished" or self.finished_active_ns is None:
            return None
        return self.finished_active_ns / 1e9 + move_penalty_s * self.moves

    # -- the fold -----------------------------------------------------------------
    def apply(self, event: LoggedEvent) -> "TrialState":
        if self.running and self.last_t_ns is not None:
            self.active_ns += max(0, event.t_ns - self.last_t_ns)
        self.last_t_ns = event.t_ns
        self.last_seq = event.seq
        p = event.payload
        match event.kind:
            case "trial_created":
                self.maze, self.targets = p["maze"], list(p["targets"])
                self.backend, self.driver = p["backend"], p["driver"]
            case "connect":
                self.connected.add(p["role"])
            case "disconnect":
                self.connected.discard(p["role"])
            case "phase":
                if self.phase == "waiting" and p["phase"] in RUNNING_PHASES:
                    self.started_ns = event.t_ns
                self.phase = p["phase"]
                if p.get("target_index") is not None:
                    self.target_index = p["target_index"]
                if self.phase == "finished":
                    self.finished_active_ns = self.active_ns
            case "paused":
                self.pause_reasons.add(p["reason"])
            case "resumed":
                self.pause_reasons.discard(p["reason"])
            case "move_executed":
                if p["outcome"] in ("ok", "collision"):
                    self.moves += 1
                if p.get("collision"):
                    self.collisions += 1
            case "frame":
                if p.get("source", "driver") == "driver":
                    self.last_frame_id = p["frame_id"]
            case "pose":
                self.pose = (p["x"], p["y"], p["heading"])
            case "localization":
                self.localization = dict(p)
            case "target_claimed":
                self.pending_claim = dict(p)
            case "target_confirmed":
                self.pending_claim = None
                self.confirmed.append(dict(p))
            case "target_rejected":
                self.pending_claim = None
        return self


def fold(events: Iterable[LoggedEvent]) -> TrialState:
    state = TrialState()
    for event in events:
        state.apply(event)
    return state

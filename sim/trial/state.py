"""`TrialState`: everything about a trial, rebuilt from its events alone.

`fold(events)` is pure: the same events always give the same state, so a restarted server
resumes a trial from the database, and the leaderboard and exports read the same truth.
The trial clock runs only while localizing or navigating and nothing pauses it; it does not
run across a server restart (`Restarted`).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

from sim.trial import events as ev
from sim.trial.events import LoggedEvent
from sim.trial.specs import BackendKind, BackendSpec
from sim.trial.vocabulary import EXPERIMENTER_PAUSE, PARTICIPANTS, FrameSource, Move, Outcome, Phase, Role

__all__ = ["LoggedEvent", "TrialState", "fold", "trial_score"]


def trial_score(active_s: float, moves: int, move_penalty_s: float) -> float:
    """A finished trial's score: trial-clock seconds to the last target confirmed plus a penalty
    per executed move (the leaderboard's and the report's one rule)."""
    return active_s + move_penalty_s * moves


@dataclass
class Away:
    """A participant missing from a running trial: the grace period runs while the server does."""

    since_ns: int
    carried_ns: int = 0  # time away before the last restart

    def away_ns(self, now_ns: int) -> int:
        return self.carried_ns + max(0, now_ns - self.since_ns)


@dataclass
class TrialState:
    maze: str = ""
    targets: list[str] = field(default_factory=list)
    backend: str = "sim"
    driver: str = "human"
    commander: str = "human"
    phase: Phase = Phase.WAITING
    target_index: int = 0
    connected: set[Role] = field(default_factory=set)
    joined: set[Role] = field(default_factory=set)  # every seat that was ever opened
    pause_reasons: set[str] = field(default_factory=set)
    active_ns: int = 0  # clock time while running, up to `last_t_ns`
    last_t_ns: int | None = None
    started_ns: int | None = None
    moves: int = 0  # executed moves (ok or collision); refused ones do not count
    refused: int = 0  # move requests refused: as they came (`MovesRefused.count`) or by the robot
    collisions: int = 0
    moves_in_flight: dict[str, tuple[Move, int]] = field(default_factory=dict)  # id -> (action, asked at)
    move_ids: set[str] = field(default_factory=set)  # every move id ever requested
    last_move_ns: int | None = None  # when the last executed move was requested
    away: dict[Role, Away] = field(default_factory=dict)
    last_frame_id: int | None = None
    pending_claim: ev.TargetClaimed | None = None
    pose: tuple[float, float, float] | None = None  # last sampled true pose (x, y, theta)
    start: tuple[float, float, float] | None = None  # the simulated robot's start, where one was chosen
    seed: int | None = None  # the agents' seed, where one was chosen
    localization: ev.Localized | None = None  # the Commander's mark
    confirmed: list[ev.TargetConfirmed] = field(default_factory=list)
    finished_active_ns: int | None = None  # active time at the last confirmation
    abort_reason: str | None = None  # why it was aborted, where the log says
    pause_note: str | None = None  # why the experimenter paused it (while paused), where they said
    join_by_ns: int | None = None  # a lobby's trial: when seats still unopened abort it
    time_cap_s: float | None = None  # a practice: the trial clock's limit, past which it is aborted
    last_seq: int = 0

    # -- derived ------------------------------------------------------------------
    @property
    def running(self) -> bool:
        return self.phase.running and not self.pause_reasons

    @property
    def seats_needed(self) -> tuple[Role, ...]:
        """The seats a trial waits for before it starts: both participants, and the rover when
        one is in the robot seat (a trial cannot start on a robot that is not connected)."""
        rover = BackendSpec.parse(self.backend).kind == BackendKind.ROBOT
        return PARTICIPANTS + ((Role.ROBOT,) if rover else ())

    @property
    def waiting_for(self) -> list[Role]:
        """The seats still missing while the trial waits to start."""
        if self.phase != Phase.WAITING:
            return []
        return [role for role in self.seats_needed if role not in self.connected]

    @property
    def over(self) -> bool:
        return self.phase.over

    @property
    def current_target(self) -> str | None:
        if self.phase.running and self.target_index < len(self.targets):
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
        if self.phase != Phase.FINISHED or self.finished_active_ns is None:
            return None
        return trial_score(self.finished_active_ns / 1e9, self.moves, move_penalty_s)

    # -- the fold -----------------------------------------------------------------
    def apply(self, logged: LoggedEvent) -> TrialState:
        return self.apply_event(ev.typed(logged), logged.seq, logged.t_ns)

    def apply_event(self, event: ev.Event | None, seq: int, t_ns: int) -> TrialState:
        restarted = isinstance(event, ev.Restarted)
        if self.running and self.last_t_ns is not None and not restarted:
            self.active_ns += max(0, t_ns - self.last_t_ns)
        if restarted and self.last_t_ns is not None:
            # The server's downtime counts for no one; its last event (a `still_away` at most a
            # second before the crash, while anyone is away) is when it was last up.
            for away in self.away.values():
                away.carried_ns, away.since_ns = away.away_ns(self.last_t_ns), t_ns
        self.last_t_ns = t_ns
        self.last_seq = seq
        match event:
            case ev.TrialCreated():
                self.maze, self.targets = event.maze, list(event.targets)
                self.backend, self.driver, self.commander = event.backend, event.driver, event.commander
                self.start, self.seed, self.time_cap_s = event.start, event.seed, event.time_cap_s
                if event.join_timeout_s is not None:
                    self.join_by_ns = t_ns + round(event.join_timeout_s * 1e9)
            case ev.Connected(role=role):
                self.connected.add(role)
                self.joined.add(role)
                self.away.pop(role, None)
            case ev.Disconnected(role=role):
                self.connected.discard(role)
                if role in PARTICIPANTS and self.phase.running:
                    self.away[role] = Away(t_ns)
            case ev.PhaseChanged(phase=phase, target_index=index, reason=reason):
                if phase == Phase.ABORTED:
                    self.abort_reason = reason
                if self.phase == Phase.WAITING and phase.running:
                    self.started_ns = t_ns
                self.phase = phase
                if index is not None:
                    self.target_index = index
                if phase == Phase.FINISHED:
                    self.finished_active_ns = self.active_ns
                if phase.over:
                    self.away.clear()
            case ev.Restarted(paused=reasons):
                self.pause_reasons.update(reasons)
            case ev.Paused(reason=reason, note=note):
                self.pause_reasons.add(reason)
                if reason == EXPERIMENTER_PAUSE:
                    self.pause_note = note
            case ev.Resumed(reason=reason):
                self.pause_reasons.discard(reason)
                if reason == EXPERIMENTER_PAUSE:
                    self.pause_note = None
            case ev.MoveRequested(move_id=move_id, action=action):
                self.move_ids.add(move_id)
                self.moves_in_flight[move_id] = (action, t_ns)
            case ev.MoveExecuted(move_id=move_id, outcome=outcome, collision=collision):
                _, asked_ns = self.moves_in_flight.pop(move_id, (None, t_ns))
                if outcome != Outcome.REFUSED:
                    self.moves += 1
                    self.last_move_ns = asked_ns
                else:
                    self.refused += 1
                if collision:
                    self.collisions += 1
            case ev.MovesRefused(count=count):
                self.refused += count
            case ev.FrameRecorded(source=FrameSource.DRIVER, frame_id=frame_id):
                self.last_frame_id = frame_id
            case ev.PoseSampled(x=x, y=y, heading=heading):
                self.pose = (x, y, heading)
            case ev.Localized():
                self.localization = event
            case ev.TargetClaimed():
                self.pending_claim = event
            case ev.TargetConfirmed():
                self.pending_claim = None
                self.confirmed.append(event)
            case ev.TargetRejected():
                self.pending_claim = None
        return self


def fold(events: Iterable[LoggedEvent]) -> TrialState:
    state = TrialState()
    for event in events:
        state.apply(event)
    return state

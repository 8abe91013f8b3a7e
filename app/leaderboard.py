"""The leaderboard: human teams and agent Drivers, ranked apart, each by its best finished trial.

Score = trial-clock seconds from start to the last target confirmed + a penalty per move.
Unfinished, aborted and excluded trials do not score. A trial whose Driver was an agent
(`agent:<name>`) never counts on its team's row: it scores for the agent, with the team as its
Commander. An oracle (`oracle:<name>`, a baseline that drives by the true pose) never ranks at all.
"""

from __future__ import annotations

from dataclasses import dataclass

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.db.models import Participant, Team, Trial
from app.trial.specs import SeatKind, SeatSpec
from app.trial.vocabulary import Phase


@dataclass(frozen=True)
class TeamStanding:
    """A human team: both seats filled by its members."""

    rank: int
    team: str
    drivers: tuple[str, ...]  # who drove its finished trials
    completed: int
    best_s: float
    mean_s: float


@dataclass(frozen=True)
class AgentStanding:
    """An agent in the Driver's seat, with the teams whose member commanded it."""

    rank: int
    agent: str  # e.g. "agent:seq2seq"
    commanders: tuple[str, ...]
    completed: int
    best_s: float
    mean_s: float


def trial_score(active_s: float, moves: int, move_penalty_s: float) -> float:
    return active_s + move_penalty_s * moves


def _finished(db: Session):
    return db.execute(
        select(Trial, Team.name)
        .join(Team, Team.id == Trial.team_id)
        .where(Trial.phase == Phase.FINISHED, Trial.active_s.is_not(None), Trial.excluded_reason.is_(None))
    ).all()


def _ranked(
    groups: dict[str, tuple[list[float], set[str]]],
) -> list[tuple[int, str, tuple[str, ...], int, float, float]]:
    """(rank, key, sorted names, count, best, mean), best first (ties by key)."""
    ordered = sorted(groups.items(), key=lambda kv: (min(kv[1][0]), kv[0]))
    return [
        (i + 1, key, tuple(sorted(names)), len(s), min(s), sum(s) / len(s))
        for i, (key, (s, names)) in enumerate(ordered)
    ]


def standings(db: Session, move_penalty_s: float) -> list[TeamStanding]:
    """Human teams, by their best trial driven by one of their members."""
    names = dict(db.execute(select(Participant.id, Participant.name)).all())
    groups: dict[str, tuple[list[float], set[str]]] = {}
    for trial, team in _finished(db):
        if not SeatSpec.parse(trial.driver).human:
            continue
        scores, drivers = groups.setdefault(team, ([], set()))
        scores.append(trial_score(trial.active_s, trial.moves, move_penalty_s))
        if trial.driver_id in names:
            drivers.add(names[trial.driver_id])
    return [TeamStanding(*row) for row in _ranked(groups)]


def agent_standings(db: Session, move_penalty_s: float) -> list[AgentStanding]:
    """Agent Drivers, by their best trial with any Commander."""
    groups: dict[str, tuple[list[float], set[str]]] = {}
    for trial, team in _finished(db):
        if SeatSpec.parse(trial.driver).kind != SeatKind.AGENT:
            continue
        scores, commanders = groups.setdefault(trial.driver, ([], set()))
        scores.append(trial_score(trial.active_s, trial.moves, move_penalty_s))
        commanders.add(team)
    return [AgentStanding(*row) for row in _ranked(groups)]

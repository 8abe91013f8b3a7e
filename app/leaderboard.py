"""The leaderboard: human teams, human-agent teams and agent pairs, ranked apart, each by its best
finished trial.

Score = trial-clock seconds from start to the last target confirmed + a penalty per move.
Unfinished, aborted and excluded trials do not score. A trial with an agent (`agent:<name>`) in
one seat never counts on its team's row: it scores for the agent in that seat, with the teams
whose member held the other seat. A trial with agents in both seats scores for the pair (it has
no team). An oracle (`oracle:<name>`, a baseline that plays by the true pose) never ranks at all.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.db.models import Participant, Team, Trial
from sim.trial.specs import SeatKind, SeatSpec
from sim.trial.state import trial_score
from sim.trial.vocabulary import Phase, Role


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
    """An agent in one seat, with the teams whose member held the other."""

    rank: int
    seat: Role
    agent: str  # e.g. "agent:seq2seq"
    partners: tuple[str, ...]
    completed: int
    best_s: float
    mean_s: float


@dataclass(frozen=True)
class PairStanding:
    """Agents in both seats."""

    rank: int
    commander: str
    driver: str
    completed: int
    best_s: float
    mean_s: float


def _finished(db: Session, study: str | None) -> list[tuple[Trial, str | None, float]]:
    """(trial, its team's name, or None for an agent pair, its active seconds); with `study`, only that study's trials."""
    query = (
        select(Trial, Team.name)
        .outerjoin(Team, Team.id == Trial.team_id)
        .where(Trial.phase == Phase.FINISHED, Trial.active_s.is_not(None), Trial.excluded_reason.is_(None))
    )
    if study is not None:
        query = query.where(Trial.study == study)
    return [(trial, team, trial.active_s) for trial, team in db.execute(query) if trial.active_s is not None]


def _ranked(
    groups: dict[Any, tuple[list[float], set[str]]],
) -> list[tuple[int, Any, tuple[str, ...], int, float, float]]:
    """(rank, key, sorted names, count, best, mean), best first (ties by key)."""
    ordered = sorted(groups.items(), key=lambda kv: (min(kv[1][0]), kv[0]))
    return [
        (i + 1, key, tuple(sorted(names)), len(s), min(s), sum(s) / len(s))
        for i, (key, (s, names)) in enumerate(ordered)
    ]


def standings(db: Session, move_penalty_s: float, study: str | None = None) -> list[TeamStanding]:
    """Human teams, by their best trial driven by one of their members."""
    names = dict(db.execute(select(Participant.id, Participant.name)).all())
    groups: dict[str, tuple[list[float], set[str]]] = {}
    for trial, team, active_s in _finished(db, study):
        if team is None or not (SeatSpec.parse(trial.driver).human and SeatSpec.parse(trial.commander).human):
            continue
        scores, drivers = groups.setdefault(team, ([], set()))
        scores.append(trial_score(active_s, trial.moves, move_penalty_s))
        if trial.driver_id in names:
            drivers.add(names[trial.driver_id])
    return [TeamStanding(*row) for row in _ranked(groups)]


def agent_standings(db: Session, move_penalty_s: float, study: str | None = None) -> list[AgentStanding]:
    """Agents in one seat beside a person, by their best trial; Drivers first, then Commanders."""
    groups: dict[tuple[Role, str], tuple[list[float], set[str]]] = {}
    for trial, team, active_s in _finished(db, study):
        seats = {Role.DRIVER: trial.driver, Role.COMMANDER: trial.commander}
        kinds = {role: SeatSpec.parse(spec).kind for role, spec in seats.items()}
        agents = [(role, seats[role]) for role, kind in kinds.items() if kind == SeatKind.AGENT]
        if len(agents) != 1 or SeatKind.HUMAN not in kinds.values() or team is None:
            continue
        scores, partners = groups.setdefault(agents[0], ([], set()))
        scores.append(trial_score(active_s, trial.moves, move_penalty_s))
        partners.add(team)
    rows = []
    for seat in (Role.DRIVER, Role.COMMANDER):
        mine = {agent: group for (role, agent), group in groups.items() if role == seat}
        rows += [
            AgentStanding(rank, seat, agent, partners, completed, best, mean)
            for rank, agent, partners, completed, best, mean in _ranked(mine)
        ]
    return rows


def pair_standings(db: Session, move_penalty_s: float, study: str | None = None) -> list[PairStanding]:
    """Agents in both seats, by the pair's best trial."""
    groups: dict[tuple[str, str], tuple[list[float], set[str]]] = {}
    for trial, _team, active_s in _finished(db, study):
        if SeatSpec.parse(trial.commander).kind == SeatSpec.parse(trial.driver).kind == SeatKind.AGENT:
            scores, _ = groups.setdefault((trial.commander, trial.driver), ([], set()))
            scores.append(trial_score(active_s, trial.moves, move_penalty_s))
    return [
        PairStanding(rank, commander, driver, completed, best, mean)
        for rank, (commander, driver), _, completed, best, mean in _ranked(groups)
    ]

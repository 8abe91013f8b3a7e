"""The leaderboard: teams ranked by their best finished trial.

Score = trial-clock seconds from start to the last target confirmed + a penalty per move.
Unfinished and aborted trials do not score.
"""

from __future__ import annotations

from dataclasses import dataclass

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.db.models import Team, Trial
from app.trial.vocabulary import Phase


@dataclass(frozen=True)
class TeamStanding:
    rank: int
    team: str
    completed: int
    best_s: float
    mean_s: float


def trial_score(active_s: float, moves: int, move_penalty_s: float) -> float:
    return active_s + move_penalty_s * moves


def standings(db: Session, move_penalty_s: float) -> list[TeamStanding]:
    rows = db.execute(select(Team.name, Trial.active_s, Trial.moves).join(Trial, Trial.team_id == Team.id)
                      .where(Trial.phase == Phase.FINISHED, Trial.active_s.is_not(None)))
    scores: dict[str, list[float]] = {}
    for team, active_s, moves in rows:
        scores.setdefault(team, []).append(trial_score(active_s, moves, move_penalty_s))
    ranked = sorted(scores.items(), key=lambda kv: (min(kv[1]), kv[0]))
    return [TeamStanding(i + 1, team, len(s), min(s), sum(s) / len(s)) for i, (team, s) in enumerate(ranked)]

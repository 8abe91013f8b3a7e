"""The leaderboard ranks teams by their best finished trial; unfinished trials do not score."""

from __future__ import annotations

import httpx

from app.db.models import Trial
from app.leaderboard import standings
from app.trial.setup import create_participant, create_team
from tests.app.live import ServerThread


def add_trials(services, team_name: str, trials: list[tuple[str, float | None, int]]) -> None:
    with services.db.begin() as db:
        a = create_participant(db, f"{team_name}-a")
        b = create_participant(db, f"{team_name}-b")
        team = create_team(db, team_name, a.id, b.id)
        for i, (phase, active_s, moves) in enumerate(trials):
            db.add(Trial(team_id=team.id, maze=f"m{i}", targets=["jar", "mug", "paddle"], backend="sim",
                         driver="human", phase=phase, active_s=active_s, moves=moves))


def test_teams_ranked_by_best_score_with_count_and_mean(settings):
    with ServerThread(settings) as server:
        services = server.services
        add_trials(services, "Slow", [("finished", 300.0, 100)])  # 400 s
        add_trials(services, "Steady", [("finished", 100.0, 50), ("finished", 150.0, 50),  # 150, 200
                                        ("aborted", None, 5), ("navigating", None, 40)])
        add_trials(services, "Never", [("aborted", None, 3)])
        with services.db() as db:
            rows = standings(db, move_penalty_s=1.0)
            halved = standings(db, move_penalty_s=0.5)
        assert [(r.rank, r.team, r.completed) for r in rows] == [(1, "Steady", 2), (2, "Slow", 1)]
        assert rows[0].best_s == 150.0 and rows[0].mean_s == 175.0 and rows[1].best_s == 400.0
        assert halved[0].best_s == 125.0
        page = httpx.get(server.url + "/leaderboard").text
        assert page.index("Steady") < page.index("Slow") and "Never" not in page
        assert "175.0" in page

"""The leaderboard ranks teams by their best finished trial, agent Drivers apart; unfinished trials do not score."""

from __future__ import annotations

import httpx
from sqlalchemy import select

from app.db.models import Team, Trial
from app.leaderboard import agent_standings, pair_standings, standings
from app.trial.setup import create_participant, create_team


def add_trials(services, team_name: str, trials: list[tuple[str, float | None, int]]) -> None:
    with services.db.begin() as db:
        a = create_participant(db, f"{team_name}-a")
        b = create_participant(db, f"{team_name}-b")
        team = create_team(db, team_name, a.id, b.id)
        for i, (phase, active_s, moves) in enumerate(trials):
            db.add(
                Trial(
                    team_id=team.id,
                    maze=f"m{i}",
                    targets=["jar", "mug", "paddle"],
                    backend="sim",
                    driver="human",
                    phase=phase,
                    active_s=active_s,
                    moves=moves,
                )
            )


def test_teams_ranked_by_best_score_with_count_and_mean(server):
    services = server.services
    add_trials(services, "Slow", [("finished", 300.0, 100)])  # 400 s
    add_trials(
        services,
        "Steady",
        [
            ("finished", 100.0, 50),
            ("finished", 150.0, 50),  # 150, 200
            ("aborted", None, 5),
            ("navigating", None, 40),
        ],
    )
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


def test_agent_trials_rank_apart_and_never_count_for_the_team(server):
    services = server.services
    add_trials(services, "Owls", [("finished", 200.0, 40)])  # 240 s, driven by Owls-b
    with services.db.begin() as db:
        team = db.scalar(select(Team).where(Team.name == "Owls"))
        for driver, active_s, moves in (
            ("agent:dialog", 50.0, 30),
            ("agent:dialog", 70.0, 30),
            ("oracle:shortest", 10.0, 20),  # cheats: it ranks nowhere
            ("agent:random", 500.0, 300),
            ("agent:random", None, 9),
        ):
            db.add(
                Trial(
                    team_id=team.id,
                    maze="m9",
                    targets=["jar", "mug", "paddle"],
                    backend="sim",
                    driver=driver,
                    commander_id=team.member_a_id,
                    phase="finished" if active_s else "aborted",
                    active_s=active_s,
                    moves=moves,
                )
            )
        db.get(Trial, 1).driver_id = team.member_b_id
    with services.db() as db:
        teams = standings(db, move_penalty_s=1.0)
        agents = agent_standings(db, move_penalty_s=1.0)
    assert [(r.team, r.completed, r.best_s, r.drivers) for r in teams] == [("Owls", 1, 240.0, ("Owls-b",))]
    assert [(r.rank, r.seat, r.agent, r.completed, r.best_s, r.partners) for r in agents] == [
        (1, "driver", "agent:dialog", 2, 80.0, ("Owls",)),
        (2, "driver", "agent:random", 1, 800.0, ("Owls",)),
    ]
    page = httpx.get(server.url + "/leaderboard").text
    humans, machines = page.split('id="agent-leaderboard"')
    assert "Owls-b" in humans and "agent:" not in humans and "80.0" not in humans
    assert machines.index("agent:dialog") < machines.index("agent:random")
    assert "oracle:" not in page


def test_agent_commanders_and_agent_pairs_rank_apart_saying_who_held_which_seat(server):
    services = server.services
    add_trials(services, "Larks", [("finished", 300.0, 20)])  # 320 s, both seats theirs
    with services.db.begin() as db:
        team = db.scalar(select(Team).where(Team.name == "Larks"))
        for team_id, commander, driver, active_s in (
            (team.id, "agent:dialog", "human", 90.0),  # a person drove the agent Commander
            (None, "agent:dialog", "agent:dialog", 60.0),  # agents in both seats: no team
            (None, "agent:dialog", "agent:dialog", 100.0),
            (None, "agent:dialog", "oracle:shortest", 5.0),  # a cheat in one seat: ranks nowhere
        ):
            db.add(
                Trial(
                    team_id=team_id,
                    maze="m7",
                    targets=["jar", "mug", "paddle"],
                    backend="sim",
                    driver=driver,
                    commander=commander,
                    phase="finished",
                    active_s=active_s,
                    moves=10,
                )
            )
    with services.db() as db:
        teams = standings(db, move_penalty_s=1.0)
        agents = agent_standings(db, move_penalty_s=1.0)
        pairs = pair_standings(db, move_penalty_s=1.0)
    assert [(r.team, r.completed, r.best_s) for r in teams] == [("Larks", 1, 320.0)]
    assert [(r.seat, r.agent, r.partners, r.best_s) for r in agents] == [
        ("commander", "agent:dialog", ("Larks",), 100.0)
    ]
    assert [(r.rank, r.commander, r.driver, r.completed, r.best_s, r.mean_s) for r in pairs] == [
        (1, "agent:dialog", "agent:dialog", 2, 70.0, 90.0)
    ]
    page = httpx.get(server.url + "/leaderboard").text
    humans, rest = page.split('id="agent-leaderboard"')
    mixed, paired = rest.split('id="pair-leaderboard"')
    assert "agent:" not in humans and "Larks" in mixed and "commander" in mixed
    assert "70.0" in paired and "Larks" not in paired and "oracle:" not in page


def test_a_study_has_its_own_leaderboard_scored_with_its_move_penalty(server):
    from app.study.config import StudyFiles, template

    services = server.services
    add_trials(services, "Ours", [("finished", 100.0, 10)])
    add_trials(services, "Theirs", [("finished", 90.0, 10)])
    with services.db.begin() as db:
        team = db.scalar(select(Team).where(Team.name == "Ours"))
        db.query(Trial).filter(Trial.team_id == team.id).update({"study": "pilot"})
    StudyFiles(services.settings.data_dir / "studies").save(
        template("pilot").model_copy(update={"move_penalty_s": 5.0})
    )
    page = httpx.get(server.url + "/leaderboard?study=pilot").text
    assert "study pilot" in page and "Ours" in page and "Theirs" not in page
    assert "150.0" in page and "+ 5.0 s per move" in page, "100 s + 5 s x 10 moves"
    everyone = httpx.get(server.url + "/leaderboard").text
    assert "Ours" in everyone and "Theirs" in everyone

"""Creating trials: a maze the team has never seen (least used first), three targets in order,
a robot backend and who drives. The `trial_created` event is written with the trial row."""

from __future__ import annotations

import random
from collections import Counter
from collections.abc import Mapping

from sqlalchemy import or_, select
from sqlalchemy.orm import Session

from app.db.models import Event, Participant, Robot, Team, Trial
from app.trial.events import TrialCreated
from app.trial.vocabulary import Phase, Role
from sim.core.labels import OBJECTS


class TrialSetupError(ValueError):
    """A trial that cannot be created as asked; the message names the field."""


def mazes_seen(db: Session, team: Team) -> set[str]:
    """Mazes either member has played in, in any team."""
    members = (team.member_a_id, team.member_b_id)
    teams = select(Team.id).where(or_(Team.member_a_id.in_(members), Team.member_b_id.in_(members)))
    return set(db.scalars(select(Trial.maze).where(Trial.team_id.in_(teams))))


def suggest_maze(db: Session, team: Team, names: list[str]) -> str | None:
    """The least-used maze the team has never seen (ties by name)."""
    seen = mazes_seen(db, team)
    use = Counter(db.scalars(select(Trial.maze)))
    fresh = [n for n in names if n not in seen]
    return min(fresh, key=lambda n: (use[n], n)) if fresh else None


def parse_targets(text: str, rng: random.Random) -> list[str]:
    text = text.strip().lower()
    if text in ("", "random"):
        order = list(OBJECTS)
        rng.shuffle(order)
        return order
    order = [t.strip() for t in text.replace(" ", ",").split(",") if t.strip()]
    if sorted(order) != sorted(OBJECTS):
        raise TrialSetupError(f"targets {text!r}: give each of {', '.join(OBJECTS)} once, in order")
    return order


def check_driver(driver: str, agents: Mapping[str, str | None] | None) -> None:
    """`human`, or an agent or oracle that can start: `agents` is `available_drivers(services)`."""
    if driver == "human":
        return
    if agents is None or driver not in agents:
        known = ", ".join(agents or ())
        raise TrialSetupError(f"driver {driver!r} is neither 'human' nor a known agent ({known})")
    if agents[driver] is not None:
        raise TrialSetupError(f"driver {driver!r} cannot start: {agents[driver]}")


def create_trial(
    db: Session,
    *,
    team_id: int,
    maze: str,
    targets: list[str],
    backend: str,
    driver: str,
    commander_id: int | None,
    maze_names: list[str],
    now_ns: int,
    agents: Mapping[str, str | None] | None = None,
) -> Trial:
    """`agents` (`available_drivers(services)`) is needed when an agent drives."""
    check_driver(driver, agents)
    team = db.get(Team, team_id)
    if team is None:
        raise TrialSetupError(f"team {team_id} does not exist")
    if maze not in maze_names:
        raise TrialSetupError(f"maze {maze!r} is not in the library")
    if maze in mazes_seen(db, team):
        raise TrialSetupError(f"maze {maze!r}: team {team.name!r} has already seen it")
    if backend.startswith("robot:"):
        robot_id = backend.removeprefix("robot:")
        robot = db.get(Robot, int(robot_id)) if robot_id.isdigit() else None
        if robot is None or robot.role != Role.DRIVER:
            raise TrialSetupError(f"backend {backend!r}: no registered rover with id {robot_id!r}")
    elif backend != "sim":
        raise TrialSetupError(f"backend {backend!r} is neither 'sim' nor 'robot:<id>'")
    members = (team.member_a_id, team.member_b_id)
    commander_id = commander_id or team.member_a_id
    if commander_id not in members:
        raise TrialSetupError(f"commander {commander_id} is not a member of team {team.name!r}")
    driver_id = None
    if driver == "human":
        driver_id = members[1] if commander_id == members[0] else members[0]
    trial = Trial(
        team_id=team.id,
        maze=maze,
        targets=targets,
        backend=backend,
        driver=driver,
        commander_id=commander_id,
        driver_id=driver_id,
        phase=str(Phase.WAITING),
        moves=0,
    )
    db.add(trial)
    db.flush()
    created = TrialCreated(maze=maze, targets=targets, backend=backend, driver=driver)
    db.add(Event(trial_id=trial.id, seq=1, kind=created.kind, t_ns=now_ns, payload=created.payload()))
    return trial


def create_team(db: Session, name: str, member_a_id: int, member_b_id: int) -> Team:
    name = name.strip()
    if not name:
        raise TrialSetupError("team name is empty")
    if member_a_id == member_b_id:
        raise TrialSetupError("a team needs two different participants")
    for pid in (member_a_id, member_b_id):
        if db.get(Participant, pid) is None:
            raise TrialSetupError(f"participant {pid} does not exist")
    if db.scalar(select(Team).where(Team.name == name)) is not None:
        raise TrialSetupError(f"team {name!r} already exists")
    team = Team(name=name, member_a_id=member_a_id, member_b_id=member_b_id)
    db.add(team)
    db.flush()
    return team


def create_participant(db: Session, name: str) -> Participant:
    name = name.strip()
    if not name:
        raise TrialSetupError("participant name is empty")
    if db.scalar(select(Participant).where(Participant.name == name)) is not None:
        raise TrialSetupError(f"participant {name!r} already exists")
    participant = Participant(name=name)
    db.add(participant)
    db.flush()
    return participant

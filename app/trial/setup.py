"""Creating trials: a maze whose layout the team has never seen (least used first), three targets
in order, a robot backend and who drives. Mazes are compared by physical layout (`sim.tasks.layouts`):
`layouts` maps each maze of the library to its layout's id. The `trial_created` event is written with the trial row."""

from __future__ import annotations

import random
from collections import Counter
from collections.abc import Mapping

from sqlalchemy import or_, select
from sqlalchemy.orm import Session

from app.db.models import Event, Participant, Robot, Team, Trial
from app.trial.events import TrialCreated
from app.trial.lifecycle import live_trial_of
from app.trial.specs import HUMAN, SIM, BackendSpec
from app.trial.vocabulary import Phase, Role
from sim.core.labels import OBJECTS


class TrialSetupError(ValueError):
    """A trial that cannot be created as asked; the message names the field."""


def layouts_seen(db: Session, team: Team, layouts: Mapping[str, str]) -> dict[str, str]:
    """Each layout either member has played in, in any team -> a maze they played it as (a maze
    no longer in the library is a layout of its own)."""
    members = (team.member_a_id, team.member_b_id)
    teams = select(Team.id).where(or_(Team.member_a_id.in_(members), Team.member_b_id.in_(members)))
    played = sorted(set(db.scalars(select(Trial.maze).where(Trial.team_id.in_(teams)))))
    return {layouts.get(maze, maze): maze for maze in played}


def suggest_maze(db: Session, team: Team, layouts: Mapping[str, str]) -> str | None:
    """A maze of the least-used layout the team has never seen; within it the least-used maze
    (ties by name)."""
    seen = layouts_seen(db, team, layouts)
    use = Counter(db.scalars(select(Trial.maze)))
    layout_use: Counter[str] = Counter()
    for maze, count in use.items():
        layout_use[layouts.get(maze, maze)] += count
    fresh = [n for n, layout in layouts.items() if layout not in seen]
    return min(fresh, key=lambda n: (layout_use[layouts[n]], use[n], n)) if fresh else None


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
    """`human`, or an agent or oracle that can start: `agents` is `available_drivers(services.drivers)`."""
    if driver == str(HUMAN):
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
    layouts: Mapping[str, str],
    now_ns: int,
    agents: Mapping[str, str | None] | None = None,
) -> Trial:
    """`layouts`: each maze of the library -> its layout (`Mazes.layouts()`); `agents`
    (`available_drivers(services.drivers)`) is needed when an agent drives."""
    check_driver(driver, agents)
    team = db.get(Team, team_id)
    if team is None:
        raise TrialSetupError(f"team {team_id} does not exist")
    live = live_trial_of(db, (team.member_a_id, team.member_b_id))
    if live is not None:
        raise TrialSetupError(
            f"team {team.name!r}: a member is in trial {live.id}, which is {live.phase}; a participant "
            f"is in one live trial at a time (let it finish, or abort it)"
        )
    if maze not in layouts:
        raise TrialSetupError(f"maze {maze!r} is not in the library")
    played = layouts_seen(db, team, layouts).get(layouts[maze])
    if played == maze:
        raise TrialSetupError(f"maze {maze!r}: team {team.name!r} has already seen it")
    if played is not None:
        raise TrialSetupError(
            f"maze {maze!r} is layout {layouts[maze]}, which team {team.name!r} has already seen as {played}"
        )
    try:
        spec = BackendSpec.parse(backend)
    except ValueError:
        spec = None
    if spec is not None and spec.robot_id is not None:
        robot = db.get(Robot, spec.robot_id)
        if robot is None or robot.role != Role.DRIVER:
            raise TrialSetupError(f"backend {backend!r}: no registered rover with id {spec.arg!r}")
    elif spec != SIM:
        raise TrialSetupError(f"backend {backend!r} is neither 'sim' nor 'robot:<id>'")
    members = (team.member_a_id, team.member_b_id)
    commander_id = commander_id or team.member_a_id
    if commander_id not in members:
        raise TrialSetupError(f"commander {commander_id} is not a member of team {team.name!r}")
    driver_id = None
    if driver == str(HUMAN):
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

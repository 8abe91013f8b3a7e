"""Creating trials: a maze whose layout the team has never seen (least used first), three targets
in order, a robot backend and who holds each seat (`human`, or an agent for the seat: see
`app.seats.registry`). Mazes are compared by physical layout (`sim.tasks.layouts`): `layouts`
maps each maze of the library to its layout's id. A trial with agents in both seats has no team:
no person sits, so nobody sees its layout. The `trial_created` event is written with the trial row."""

from __future__ import annotations

import math
import random
from collections import Counter
from collections.abc import Collection, Mapping

from sqlalchemy import or_, select
from sqlalchemy.orm import Session

from app.db.models import Event, Participant, Robot, Team, Trial
from app.trial.lifecycle import live_trial_of
from sim.core.labels import OBJECTS
from sim.trial.events import Connected, TrialCreated
from sim.trial.specs import HUMAN, SIM, BackendSpec
from sim.trial.vocabulary import Phase, Role


class TrialSetupError(ValueError):
    """A trial that cannot be created as asked; the message names the field."""


def layouts_seen(db: Session, team: Team | None, layouts: Mapping[str, str]) -> dict[str, str]:
    """Each layout either member has played in, in any team -> a maze they played it as (a maze
    no longer in the library is a layout of its own). No team (agents in both seats): none."""
    if team is None:
        return {}
    return layouts_seen_by(db, (team.member_a_id, team.member_b_id), layouts)


def layouts_seen_by(db: Session, members: tuple[int, ...], layouts: Mapping[str, str]) -> dict[str, str]:
    """Each layout these participants have played in, in any team -> a maze they played it as
    (not the layout of a trial aborted with its Commander's seat never opened: nobody saw the map)."""
    teams = select(Team.id).where(or_(Team.member_a_id.in_(members), Team.member_b_id.in_(members)))
    trials = dict(db.execute(select(Trial.id, Trial.maze).where(Trial.team_id.in_(teams))).all())
    unseen = [i for i, roles in never_joined(db, trials).items() if Role.COMMANDER in roles]
    played = sorted({maze for trial_id, maze in trials.items() if trial_id not in unseen})
    return {layouts.get(maze, maze): maze for maze in played}


def never_joined(db: Session, trial_ids: Collection[int]) -> dict[int, list[Role]]:
    """The aborted ones of these trials in which a person's seat was never opened -> those seats.
    Such a trial is no one's in a study's plan; its layout is unseen when it was the Commander's."""
    aborted = {
        t.id: t for t in db.scalars(select(Trial).where(Trial.id.in_(trial_ids), Trial.phase == str(Phase.ABORTED)))
    }
    joined: dict[int, set[str]] = {i: set() for i in aborted}
    for event in db.scalars(select(Event).where(Event.trial_id.in_(aborted), Event.kind == Connected.kind)):
        joined[event.trial_id].add(str(event.payload.get("role")))
    missing = {
        i: [
            role
            for role, spec in ((Role.COMMANDER, t.commander), (Role.DRIVER, t.driver))
            if spec == str(HUMAN) and str(role) not in joined[i]
        ]
        for i, t in aborted.items()
    }
    return {i: roles for i, roles in missing.items() if roles}


def suggest_maze(db: Session, team: Team | None, layouts: Mapping[str, str]) -> str | None:
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


def check_seat(role: Role, spec: str, agents: Mapping[str, str | None] | None) -> None:
    """`human`, or an agent or oracle for the seat that can start: `agents` is
    `available_agents(services, role)`."""
    if spec == str(HUMAN):
        return
    if agents is None or spec not in agents:
        known = ", ".join(agents or ())
        raise TrialSetupError(f"{role} {spec!r} is neither 'human' nor a known agent for the {role}'s seat ({known})")
    if agents[spec] is not None:
        raise TrialSetupError(f"{role} {spec!r} cannot start: {agents[spec]}")


def create_trial(
    db: Session,
    *,
    team_id: int | None,
    maze: str,
    targets: list[str],
    backend: str,
    driver: str,
    commander_id: int | None,
    layouts: Mapping[str, str],
    now_ns: int,
    agents: Mapping[str, str | None] | None = None,
    commander: str = str(HUMAN),
    commanders: Mapping[str, str | None] | None = None,
    start: tuple[float, float, float] | None = None,
    join_timeout_s: float | None = None,
    seed: int | None = None,
    time_cap_s: float | None = None,
) -> Trial:
    """`layouts`: each maze of the library -> its layout (`Mazes.layouts()`); `agents` and
    `commanders` (`available_agents(services, role)`) are needed when an agent holds that seat.
    `commander_id`: the member in the Commander's seat (default the team's first); with an agent
    Commander, the member who drives. With agents in both seats the team is not asked for (none is
    stored). `start`: where the simulated robot starts (x, y, theta; snapped to the maze's graph),
    logged with the trial; None: the simulator backend draws a start. `join_timeout_s`: a seat a
    person has not opened this long after creation aborts the trial (a study's lobby pairs).
    `seed`: the agents' (default the trial's id), logged with the trial. `time_cap_s`: the trial
    clock's limit (a study's practice), past which the trial is aborted."""
    check_seat(Role.DRIVER, driver, agents)
    check_seat(Role.COMMANDER, commander, commanders)
    people = str(HUMAN) in (driver, commander)
    team = None
    if people:
        if team_id is None:
            raise TrialSetupError("choose a team (form one first): a person holds a seat")
        team = db.get(Team, team_id)
        if team is None:
            raise TrialSetupError(f"team {team_id} does not exist")
    if maze not in layouts:
        raise TrialSetupError(f"maze {maze!r} is not in the library")
    commander_id, driver_id = _seated(db, team, maze, layouts, commander_id, commander, driver)
    try:
        spec = BackendSpec.parse(backend)
    except ValueError:
        spec = None
    if start is not None and spec != SIM:
        raise TrialSetupError("a start pose is for the simulator: a rover starts where it stands")
    if spec is not None and spec.robot_id is not None:
        robot = db.get(Robot, spec.robot_id)
        if robot is None or robot.role != Role.DRIVER:
            raise TrialSetupError(f"backend {backend!r}: no registered rover with id {spec.arg!r}")
    elif spec != SIM:
        raise TrialSetupError(f"backend {backend!r} is neither 'sim' nor 'robot:<id>'")
    if start is not None and not (len(start) == 3 and all(map(math.isfinite, start))):
        raise TrialSetupError(f"start {start!r} is not a pose (x, y, theta: three finite numbers)")
    trial = Trial(
        team_id=team.id if team is not None else None,
        maze=maze,
        targets=targets,
        backend=backend,
        driver=driver,
        commander=commander,
        commander_id=commander_id,
        driver_id=driver_id,
        phase=str(Phase.WAITING),
        moves=0,
    )
    db.add(trial)
    db.flush()
    created = TrialCreated(
        maze=maze,
        targets=targets,
        backend=backend,
        driver=driver,
        commander=commander,
        start=start,
        join_timeout_s=join_timeout_s,
        seed=seed,
        time_cap_s=time_cap_s,
    )
    db.add(Event(trial_id=trial.id, seq=1, kind=created.kind, t_ns=now_ns, payload=created.payload()))
    return trial


def _seated(
    db: Session,
    team: Team | None,
    maze: str,
    layouts: Mapping[str, str],
    member_id: int | None,
    commander: str,
    driver: str,
) -> tuple[int | None, int | None]:
    """(commander_id, driver_id): the team's members in the seats a person holds, once the team may
    play `maze` (no member in a live trial, its layout unseen)."""
    if team is None:
        return None, None
    members = (team.member_a_id, team.member_b_id)
    live = live_trial_of(db, members)
    if live is not None:
        raise TrialSetupError(
            f"team {team.name!r}: a member is in trial {live.id}, which is {live.phase}; a participant "
            f"is in one live trial at a time (let it finish, or abort it)"
        )
    seen = layouts_seen(db, team, layouts)
    played = seen.get(layouts[maze]) if seen else None  # a team that has seen nothing reads no layout
    if played == maze:
        raise TrialSetupError(f"maze {maze!r}: team {team.name!r} has already seen it")
    if played is not None:
        raise TrialSetupError(
            f"maze {maze!r} is layout {layouts[maze]}, which team {team.name!r} has already seen as {played}"
        )
    member_id = member_id or members[0]
    if member_id not in members:
        raise TrialSetupError(f"commander {member_id} is not a member of team {team.name!r}")
    other = members[1] if member_id == members[0] else members[0]
    if commander != str(HUMAN):
        return None, member_id
    return member_id, other if driver == str(HUMAN) else None


def restart_trial(
    db: Session,
    trial_id: int,
    layouts: Mapping[str, str],
    now_ns: int,
    agents: Mapping[str, str | None] | None = None,
    commanders: Mapping[str, str | None] | None = None,
    join_timeout_s: float | None = None,
    seed: int | None = None,
    time_cap_s: float | None = None,
) -> Trial:
    """A new trial for an aborted one: the same seats, targets, robot and study, on a layout of
    `layouts` the team has never seen (the aborted one's counts as seen: its Commander may have had
    the map), or on the same maze when the Commander's seat was never opened (nobody saw it).
    `join_timeout_s`, `time_cap_s`: as `create_trial`'s (a study's restart keeps its deadline and cap)."""
    old = db.get(Trial, trial_id)
    if old is None:
        raise TrialSetupError(f"trial {trial_id} does not exist")
    if old.phase != Phase.ABORTED:
        raise TrialSetupError(f"trial {trial_id} is {old.phase}: only an aborted trial is restarted")
    team = db.get(Team, old.team_id) if old.team_id is not None else None
    unopened = never_joined(db, (old.id,)).get(old.id, [])
    maze = old.maze if Role.COMMANDER in unopened and old.maze in layouts else suggest_maze(db, team, layouts)
    if maze is None:
        raise TrialSetupError(f"team {team.name if team else '-'!r} has seen every layout in the library")
    trial = create_trial(
        db,
        team_id=old.team_id,
        maze=maze,
        targets=list(old.targets),
        backend=old.backend,
        driver=old.driver,
        commander_id=old.commander_id,
        layouts=layouts,
        now_ns=now_ns,
        agents=agents,
        commander=old.commander,
        commanders=commanders,
        join_timeout_s=join_timeout_s,
        seed=seed,
        time_cap_s=time_cap_s,
    )
    trial.study = old.study
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

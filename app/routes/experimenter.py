"""Experimenter pages (behind login): participants, teams, robots, trials with their join links,
and the live dashboard with the true pose, each robot's link, pause, resume and abort."""

from __future__ import annotations

import random
from collections.abc import Callable
from typing import Any
from urllib.parse import quote

from anyio import from_thread
from fastapi import APIRouter, Depends, Form, HTTPException, Request
from fastapi.responses import HTMLResponse, RedirectResponse, Response
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.db.models import Participant, Robot, Team, Trial
from app.deps import (
    AgentsDep,
    ClockDep,
    DbSession,
    HubDep,
    LogDep,
    MazesDep,
    RobotLinksDep,
    SeatTokensDep,
    SettingsDep,
    StudyFilesDep,
    experimenter_id,
)
from app.guard import csrf_protect
from app.seats.registry import available_seats, offered_agents
from app.security import SeatTokens
from app.study.config import StudyConfigError
from app.study.lobby import Lobby
from app.trial.lifecycle import Refused, delete_participant, delete_robot, delete_team, exclude_trial
from app.trial.setup import (
    TrialSetupError,
    create_participant,
    create_team,
    create_trial,
    parse_targets,
    restart_trial,
    suggest_maze,
)
from app.web import render, trial_or_404
from sim.trial.specs import HUMAN, SIM, BackendSpec, SeatSpec
from sim.trial.state import TrialState, fold
from sim.trial.vocabulary import Phase, Role

# Every state-changing request also needs this server's Origin and the page's CSRF token.
MAX_NOTES = 10_000  # characters of a trial's notes

router = APIRouter(prefix="/experimenter", dependencies=[Depends(experimenter_id), Depends(csrf_protect)])


def controls_for(phase: str, paused: list[str] | tuple[str, ...] = ()) -> list[str]:
    """The experimenter's controls that apply to a trial in `phase` (pause, resume, abort)."""
    if phase in ("finished", "aborted"):
        return []
    if phase == "waiting":
        return ["abort"]
    return ["resume" if "experimenter" in paused else "pause", "abort"]


def seat_holders(trial: Trial, names: dict[int, str]) -> dict[str, str]:
    """Who holds each seat: the participant's name, or the agent in it."""
    commander = names.get(trial.commander_id, "") if trial.commander_id is not None else trial.commander
    driver = names.get(trial.driver_id, "") if trial.driver_id is not None else trial.driver
    return {Role.COMMANDER: commander, Role.DRIVER: driver}


def join_links(request: Request, seats: SeatTokens, trial: Trial) -> dict[str, str]:
    """A link for each seat a person holds (none for an agent's)."""
    people = ((Role.COMMANDER, trial.commander), (Role.DRIVER, trial.driver))
    roles = [role for role, spec in people if SeatSpec.parse(spec).human]
    return {role: str(request.url_for("play", token=seats.issue(trial.id, role))) for role in roles}


@router.get("", response_class=HTMLResponse)
def dashboard(
    request: Request,
    db: DbSession,
    mazes: MazesDep,
    settings: SettingsDep,
    agents: AgentsDep,
    robot_links: RobotLinksDep,
    seats: SeatTokensDep,
    error: str | None = None,
) -> HTMLResponse:
    participants = db.scalars(select(Participant).order_by(Participant.name)).all()
    teams = db.scalars(select(Team).order_by(Team.name)).all()
    trials = db.scalars(select(Trial).order_by(Trial.id.desc()).limit(100)).all()
    rovers = db.scalars(select(Robot).where(Robot.role == Role.DRIVER).order_by(Robot.name)).all()
    names = {p.id: p.name for p in participants}
    team_names = {t.id: t.name for t in teams}
    # On a fresh install's first start the warm-up groups the library for a while (7 s for the
    # benchmark's mazes): until then the page lists the mazes as they are and suggests none.
    grouped = mazes.layouts_if_grouped()
    layouts = grouped if grouped is not None else {name: name for name in mazes.names()}
    suggestions = {t.id: suggest_maze(db, t, layouts) if grouped is not None else None for t in teams}
    # The robot seat: the simulator or a registered rover, by the trial's backend spec.
    backends = {str(SIM): "simulator", **{str(BackendSpec.robot(r.id)): f"{r.name} (rover)" for r in rovers}}
    return render(
        request,
        "experimenter.html",
        participants=participants,
        teams=teams,
        trials=trials,
        names=names,
        team_names=team_names,
        layouts=layouts,
        grouped=grouped is not None,
        suggestions=suggestions,
        backends=backends,
        seat_agents=available_seats(agents),
        caps=(settings.agent_moves_per_target, settings.agent_minutes_per_trial, settings.agent_messages_per_target),
        controls_for=controls_for,
        robots=robot_links.status(),
        preparation=mazes.preparation.progress(),
        # An ended trial's links only lead to a closed page: it offers its replay instead.
        links={t.id: join_links(request, seats, t) for t in trials if not Phase(t.phase).over},
        holders={t.id: seat_holders(t, names) for t in trials},
        error=error,
    )


def _redirect(error: str | None = None) -> RedirectResponse:
    return RedirectResponse("/experimenter" + (f"?error={quote(error)}" if error else ""), status_code=303)


def _create(db: Session, create: Callable[[Session], object]) -> RedirectResponse:
    """One `setup.create_*` in a transaction; back to the dashboard, naming why where it is refused."""
    try:
        with db.begin():
            create(db)
    except TrialSetupError as err:
        return _redirect(str(err))
    return _redirect()


@router.post("/participants")
def add_participant(db: DbSession, name: str = Form(max_length=80)) -> RedirectResponse:
    return _create(db, lambda db: create_participant(db, name))


@router.post("/teams")
def add_team(
    db: DbSession, name: str = Form(max_length=80), member_a: int = Form(), member_b: int = Form()
) -> RedirectResponse:
    return _create(db, lambda db: create_team(db, name, member_a, member_b))


@router.post("/trials")
def add_trial(
    db: DbSession,
    mazes: MazesDep,
    clock: ClockDep,
    agents: AgentsDep,
    hub: HubDep,
    team_id: int | None = Form(None),
    maze: str = Form(""),
    targets: str = Form("random"),
    backend: str = Form("sim"),
    driver: str = Form("human"),
    commander: str = Form("human"),
    commander_id: int | None = Form(None),
) -> RedirectResponse:
    layouts = mazes.layouts_when_read()  # a new team's trial on a maze it names reads none
    people = str(HUMAN) in (driver, commander)  # agents in both seats play without a team
    try:
        if people and team_id is None:
            raise TrialSetupError("choose a team (form one first)")
        with db.begin():
            team = db.get(Team, team_id) if people and team_id is not None else None
            if people and team is None:
                raise TrialSetupError(f"team {team_id} does not exist")
            maze = maze or suggest_maze(db, team, layouts) or ""
            if not maze:
                raise TrialSetupError(
                    f"team {team.name!r} has seen every layout in the library" if team else "the maze library is empty"
                )
            trial = create_trial(
                db,
                team_id=team_id,
                maze=maze,
                targets=parse_targets(targets, random.Random()),
                backend=backend,
                driver=driver,
                commander_id=commander_id,
                layouts=layouts,
                now_ns=clock.now_ns(),
                agents=offered_agents(agents, Role.DRIVER, driver),
                commander=commander,
                commanders=offered_agents(agents, Role.COMMANDER, commander),
            )
            trial_id = trial.id
    except TrialSetupError as err:
        return _redirect(str(err))
    mazes.preparation.first(maze)  # ready before the links are followed
    if not people:  # nobody will open a link: the trial starts now, its agents seated
        from_thread.run(hub.get, trial_id)
    return _redirect()


@router.delete("/participants/{participant_id}")
def remove_participant(db: DbSession, participant_id: int) -> dict[str, bool]:
    return _delete(db, lambda db: delete_participant(db, participant_id))


@router.delete("/teams/{team_id}")
def remove_team(db: DbSession, team_id: int) -> dict[str, bool]:
    return _delete(db, lambda db: delete_team(db, team_id))


@router.delete("/robots/{robot_id}")
def remove_robot(db: DbSession, robot_links: RobotLinksDep, robot_id: int) -> dict[str, bool]:
    connected = any(r["id"] == robot_id and r["connected"] for r in robot_links.status())
    return _delete(db, lambda db: delete_robot(db, robot_id, connected))


def _delete(db: Session, delete: Callable[[Session], object]) -> dict[str, bool]:
    """One `lifecycle.delete_*` in a transaction; 409 naming why when it is refused."""
    try:
        with db.begin():
            delete(db)
    except Refused as err:
        raise HTTPException(409, str(err)) from None
    return {"deleted": True}


@router.post("/trials/{trial_id}/restart")
def restart(
    db: DbSession,
    mazes: MazesDep,
    clock: ClockDep,
    agents: AgentsDep,
    hub: HubDep,
    files: StudyFilesDep,
    trial_id: int,
) -> RedirectResponse:
    """An aborted trial again: the same seats, targets, robot and study, on a layout the team has
    never seen (a study's: of its pool, with its join deadline; its seat pages follow it)."""
    seat_agents = available_seats(agents)
    try:
        with db.begin():
            study = trial_or_404(db, trial_id).study
            in_study = study is not None and study in files.names()  # (a study's name given by hand has no file)
            if study is not None and in_study:
                trial = Lobby(db, files.load(study), mazes.layouts(), clock.now_ns()).restart(trial_id)
            else:
                trial = restart_trial(
                    db,
                    trial_id,
                    mazes.layouts(),
                    clock.now_ns(),
                    agents=seat_agents[Role.DRIVER],
                    commanders=seat_agents[Role.COMMANDER],
                )
            new_id, maze, people = trial.id, trial.maze, str(HUMAN) in (trial.driver, trial.commander)
    except (TrialSetupError, StudyConfigError) as err:
        return _redirect(str(err))
    mazes.preparation.first(maze)
    if in_study or not people:  # a study's join deadline runs from now, seats opened or not
        from_thread.run(hub.get, new_id)
    return _redirect()


@router.post("/trials/{trial_id}/notes")
def save_notes(
    db: DbSession, trial_id: int, notes: str = Form("", max_length=MAX_NOTES), back: str = Form("trial")
) -> RedirectResponse:
    """The experimenter's notes on a trial, at any time (during or after it); private."""
    with db.begin():
        trial_or_404(db, trial_id).notes = notes.strip() or None
    page = "replay" if back == "replay" else ""
    return RedirectResponse(f"/experimenter/trials/{trial_id}" + (f"/{page}" if page else ""), status_code=303)


@router.post("/trials/{trial_id}/exclude")
def exclude(
    db: DbSession, trial_id: int, reason: str = Form("", max_length=2000), back: str = Form("dashboard")
) -> RedirectResponse:
    """Set an ended trial aside from the leaderboard and exports, with a reason (its log is kept)."""
    try:
        with db.begin():
            exclude_trial(db, trial_id, reason)
    except Refused as err:
        return _redirect(str(err))
    return RedirectResponse(f"/experimenter/trials/{trial_id}/replay" if back == "replay" else "/experimenter", 303)


@router.post("/trials/{trial_id}/{action}")
async def control(
    db: DbSession,
    log: LogDep,
    hub: HubDep,
    trial_id: int,
    action: str,
    back: str = Form("dashboard"),
    reason: str = Form("", max_length=500),
) -> RedirectResponse:
    """Pause, resume or abort (with the experimenter's reason, logged and shown to the seats); back
    to the dashboard, or to the trial's page (`back=trial`)."""
    if action not in ("pause", "resume", "abort"):
        raise HTTPException(404, f"unknown trial action {action!r}")
    trial_or_404(db, trial_id)
    page = f"/experimenter/trials/{trial_id}" if back == "trial" else "/experimenter"
    state = fold(log.load(trial_id))
    if action not in controls_for(state.phase, sorted(state.pause_reasons)):
        return _redirect(f"trial {trial_id} is {_described(state)}: {action} does not apply")
    runtime = await hub.get(trial_id)
    if action == "abort":
        runtime.abort(
            f"stopped by the experimenter: {reason.strip()}" if reason.strip() else "stopped by the experimenter"
        )
    elif action == "pause":
        runtime.pause(reason.strip() or None)
    else:
        runtime.resume()
    await log.settled()  # the pages and the lobby read the trial's phase from the database
    return RedirectResponse(page, status_code=303)


def _described(state: TrialState) -> str:
    return state.phase + (" and paused" if "experimenter" in state.pause_reasons else "")


@router.get("/api/trials")
def live(db: DbSession, hub: HubDep) -> dict[str, Any]:
    """Every trial the server has open, in any of its processes: phase, clock, moves, seats and the
    true pose; and the recorded phase of the newest trials, so pages drop what is stale once a
    trial has ended."""
    phases = dict(db.execute(select(Trial.id, Trial.phase).order_by(Trial.id.desc()).limit(100)).all())
    return {
        "trials": from_thread.run(hub.snapshots),
        "phases": {str(trial_id): phase for trial_id, phase in phases.items()},
    }


@router.get("/trials/{trial_id}", response_class=HTMLResponse)
def watch(
    request: Request, db: DbSession, log: LogDep, seats: SeatTokensDep, settings: SettingsDep, trial_id: int
) -> HTMLResponse:
    trial = trial_or_404(db, trial_id)
    state = fold(log.load(trial_id))
    names = dict(db.execute(select(Participant.id, Participant.name)).all())
    return render(
        request,
        "watch.html",
        trial=trial,
        state=state,
        links=join_links(request, seats, trial),
        holders=seat_holders(trial, names),
        controls=controls_for(state.phase, sorted(state.pause_reasons)),
        penalty=settings.move_penalty_s,
    )


@router.get("/trials/{trial_id}/map.png")
def full_map(db: DbSession, mazes: MazesDep, trial_id: int) -> Response:
    trial = trial_or_404(db, trial_id)
    return Response(mazes.full_map_png(trial.maze), media_type="image/png")

"""Replays of recorded trials, for experimenters: the page, its event log, the frames and the
trial's exports (MCAP for Foxglove, NDH/LDH instances in the benchmark's JSON).

The page (`templates/replay.html`, `static/replay.js`) plays the log back on one timeline: the
chat as it unfolded, the Driver's frames, and the full map with the true pose trace and the
Commander's estimates. Like every other reader, it reads only the event log.
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

from fastapi import APIRouter, Depends, HTTPException, Request
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse, Response
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.db.models import Team, Trial
from app.deps import DbSession, LogDep, MazesDep, SettingsDep, experimenter_id
from app.export.record import ExportError, TrialRecord
from app.export.source import load_trial
from app.guard import csrf_protect
from app.mazes import Mazes, UnknownMaze
from app.settings import Settings
from app.web import frame_file, render, replay_events, trial_or_404
from sim.core.maze import Maze

router = APIRouter(prefix="/experimenter", dependencies=[Depends(experimenter_id), Depends(csrf_protect)])
REPLAYABLE = ("finished", "aborted")


def _trial(db: Session, trial_id: int) -> tuple[Trial, str]:
    trial = trial_or_404(db, trial_id)
    team = db.get(Team, trial.team_id) if trial.team_id is not None else None
    return trial, team.name if team else ""


@router.get("/replays", response_class=HTMLResponse)
def replays(request: Request, db: DbSession, team: str | None = None) -> HTMLResponse:
    """Finished and aborted trials (of one team, when `team` is given), newest first."""
    query = (
        select(Trial, Team.name)
        .outerjoin(Team, Team.id == Trial.team_id)  # an agent pair has no team
        .where(Trial.phase.in_(REPLAYABLE))
        .order_by(Trial.id.desc())
    )
    if team:
        query = query.where(Team.name == team)
    rows = db.execute(query.limit(500)).all()
    return render(request, "replays.html", rows=rows, team=team)


@router.get("/trials/{trial_id}/replay", response_class=HTMLResponse)
def replay(request: Request, db: DbSession, trial_id: int) -> HTMLResponse:
    trial, team = _trial(db, trial_id)
    return render(request, "replay.html", trial=trial, team=team)


@router.get("/trials/{trial_id}/replay.json")
def replay_log(db: DbSession, log: LogDep, trial_id: int) -> dict[str, Any]:
    """The whole event log, with each frame's file replaced by the URL that serves it."""
    trial, team = _trial(db, trial_id)
    events = replay_events(log.load(trial_id), f"/experimenter/trials/{trial_id}")
    return {
        "trial": {
            "id": trial.id,
            "team": team,
            "maze": trial.maze,
            "targets": trial.targets,
            "phase": trial.phase,
            "backend": trial.backend,
            "driver": trial.driver,
            "excluded": trial.excluded_reason,
        },
        "events": events,
    }


@router.get("/trials/{trial_id}/frames/{frame_id}.jpg")
def frame(db: DbSession, settings: SettingsDep, trial_id: int, frame_id: int) -> FileResponse:
    return frame_file(db, settings, trial_id, frame_id)


def _record(db: Session, settings: Settings, mazes: Mazes, trial_id: int) -> tuple[TrialRecord, Maze | None]:
    try:
        record = load_trial(db, settings, trial_id)
    except ExportError as err:
        raise HTTPException(404, str(err)) from None
    try:
        return record, mazes.load(record.maze)
    except UnknownMaze:
        return record, None


@router.get("/trials/{trial_id}/export.mcap")
def export_mcap(db: DbSession, settings: SettingsDep, mazes: MazesDep, trial_id: int) -> Response:
    """The trial as one MCAP file (Foxglove), as `robotslang export ID --format mcap` writes it."""
    from app.export.mcap import write_mcap

    record, maze = _record(db, settings, mazes, trial_id)
    with tempfile.TemporaryDirectory() as tmp:
        try:
            data = write_mcap(record, maze, Path(tmp) / "trial.mcap").read_bytes()
        except ExportError as err:
            raise HTTPException(409, str(err)) from None
    return Response(
        data,
        media_type="application/octet-stream",
        headers={"Content-Disposition": f'attachment; filename="trial-{trial_id}.mcap"'},
    )


@router.get("/trials/{trial_id}/export.ndh.json")
def export_ndh(db: DbSession, settings: SettingsDep, mazes: MazesDep, trial_id: int) -> JSONResponse:
    """The trial's NDH instances (one per confirmed target) and its LDH instance, benchmark JSON."""
    from app.export.ndh import ldh_instances, ndh_instances

    record, maze = _record(db, settings, mazes, trial_id)
    if maze is None:
        raise HTTPException(409, f"maze {record.maze!r} of trial {trial_id} is not in the maze library")
    return JSONResponse(
        {"ndh": ndh_instances(record, maze), "ldh": ldh_instances(record, maze)},
        headers={"Content-Disposition": f'attachment; filename="trial-{trial_id}-ndh.json"'},
    )

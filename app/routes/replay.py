"""Replays of recorded trials, for experimenters: the page, its event log, the frames and the
trial's exports (MCAP for Foxglove, NDH/LDH instances in the benchmark's JSON).

The page (`templates/replay.html`, `static/replay.js`) plays the log back on one timeline: the
chat as it unfolded, the Driver's frames, and the full map with the true pose trace and the
Commander's estimates. Like every other reader, it reads only the event log.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from fastapi import APIRouter, Depends, HTTPException, Request
from fastapi.responses import FileResponse, HTMLResponse, JSONResponse, Response
from sqlalchemy import select

from app.db.models import Frame, Team, Trial
from app.deps import experimenter_id
from app.export.record import ExportError, TrialRecord
from app.export.source import load_trial
from app.guard import csrf_protect
from app.mazes import UnknownMaze
from app.routes.pages import render
from app.services import Services
from app.trial import events as ev
from sim.core.maze import Maze

router = APIRouter(prefix="/experimenter", dependencies=[Depends(experimenter_id), Depends(csrf_protect)])
REPLAYABLE = ("finished", "aborted")


def _trial(request: Request, trial_id: int) -> tuple[Trial, str]:
    with request.app.state.services.db() as db:
        trial = db.get(Trial, trial_id)
        if trial is None:
            raise HTTPException(404, f"trial {trial_id} does not exist")
        team = db.get(Team, trial.team_id)
        return trial, team.name if team else ""


@router.get("/replays", response_class=HTMLResponse)
def replays(request: Request, team: str | None = None):
    """Finished and aborted trials (of one team, when `team` is given), newest first."""
    with request.app.state.services.db() as db:
        query = (
            select(Trial, Team.name)
            .join(Team, Team.id == Trial.team_id)
            .where(Trial.phase.in_(REPLAYABLE))
            .order_by(Trial.id.desc())
        )
        if team:
            query = query.where(Team.name == team)
        rows = db.execute(query.limit(500)).all()
    return render(request, "replays.html", rows=rows, team=team)


@router.get("/trials/{trial_id}/replay", response_class=HTMLResponse)
def replay(request: Request, trial_id: int):
    trial, team = _trial(request, trial_id)
    return render(request, "replay.html", trial=trial, team=team)


@router.get("/trials/{trial_id}/replay.json")
def replay_log(request: Request, trial_id: int):
    """The whole event log, with each frame's file replaced by the URL that serves it."""
    trial, team = _trial(request, trial_id)
    events = replay_events(request.app.state.services.log.load(trial_id), f"/experimenter/trials/{trial_id}")
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


def replay_events(log: list[ev.LoggedEvent], base: str) -> list[dict]:
    """The log as the replay page reads it: each frame's file replaced by its URL under `base`."""
    events = []
    for e in log:
        payload = dict(e.payload)
        if e.is_(ev.FrameRecorded):
            payload.pop("path", None)
            payload["url"] = f"{base}/frames/{payload['frame_id']}.jpg"
        events.append({"seq": e.seq, "kind": e.kind, "t_ns": e.t_ns, "payload": payload})
    return events


@router.get("/trials/{trial_id}/frames/{frame_id}.jpg")
def frame(request: Request, trial_id: int, frame_id: int):
    return frame_file(request.app.state.services, trial_id, frame_id)


def frame_file(services: Services, trial_id: int, frame_id: int) -> FileResponse:
    with services.db() as db:
        rel = db.scalar(select(Frame.path).where(Frame.trial_id == trial_id, Frame.seq == frame_id))
    if rel is None:
        raise HTTPException(404, f"trial {trial_id} has no frame {frame_id}")
    path = services.settings.frames_dir / rel
    if not path.is_file():
        raise HTTPException(404, f"frame {frame_id} of trial {trial_id}: file {rel} is missing")
    return FileResponse(path, media_type="image/jpeg", headers={"Cache-Control": "private, max-age=86400"})


def _record(request: Request, trial_id: int) -> tuple[TrialRecord, Maze | None]:
    services = request.app.state.services
    with services.db() as db:
        try:
            record = load_trial(db, services.settings, trial_id)
        except ExportError as err:
            raise HTTPException(404, str(err)) from None
    try:
        return record, services.mazes.load(record.maze)
    except UnknownMaze:
        return record, None


@router.get("/trials/{trial_id}/export.mcap")
def export_mcap(request: Request, trial_id: int):
    """The trial as one MCAP file (Foxglove), as `robotslang export ID --format mcap` writes it."""
    from app.export.mcap import write_mcap

    record, maze = _record(request, trial_id)
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
def export_ndh(request: Request, trial_id: int):
    """The trial's NDH instances (one per confirmed target) and its LDH instance, benchmark JSON."""
    from app.export.ndh import ldh_instances, ndh_instances

    record, maze = _record(request, trial_id)
    if maze is None:
        raise HTTPException(409, f"maze {record.maze!r} of trial {trial_id} is not in the maze library")
    return JSONResponse(
        {"ndh": ndh_instances(record, maze), "ldh": ldh_instances(record, maze)},
        headers={"Content-Disposition": f'attachment; filename="trial-{trial_id}-ndh.json"'},
    )

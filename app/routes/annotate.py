"""The annotation pages: an annotator's queue and progress, and per trial the dialog with its
message numbers, the map with the true trace and the Commander's estimates (an aid that can be
hidden), the localization cut and the phenomena tags. Annotators see layouts and dialogs, never
a team's or a participant's name.

The experimenter's side: agreement between annotators of a study, and adjudication.
"""

from __future__ import annotations

from typing import Annotated, Any
from urllib.parse import quote

from fastapi import APIRouter, Depends, Form, HTTPException, Request
from fastapi.responses import FileResponse, HTMLResponse, RedirectResponse, Response
from sqlalchemy import select

from app.accounts import AccountError, create_account
from app.annotation.access import AnnotatorId, annotator_login
from app.annotation.agreement import answer_word
from app.annotation.dialog import estimates, messages
from app.annotation.events import TITLES, Adjudicated, AnnotationEventModel, CutMarked, Submitted, Tagged
from app.annotation.study import study_agreement
from app.cookies import logged_out
from app.db.models import AnnotationAssignment, Experimenter, Trial
from app.deps import (
    AnnotationsDep,
    AnnotatorSessionsDep,
    ClockDep,
    DbSession,
    ExperimenterId,
    LogDep,
    MazesDep,
    SettingsDep,
    StudyFilesDep,
)
from app.guard import csrf_protect
from app.security import ANNOTATOR_COOKIE, AccountRole, Login
from app.study.config import StudyFiles
from app.web import frame_file, render, replay_events

router = APIRouter(dependencies=[Depends(csrf_protect)])


def assigned_trial(trial_id: int, db: DbSession, annotator: AnnotatorId) -> Trial:
    """The trial the path names, if it is in this annotator's queue (404 otherwise)."""
    assigned = db.scalar(
        select(AnnotationAssignment.id).where(
            AnnotationAssignment.trial_id == trial_id, AnnotationAssignment.annotator_id == annotator
        )
    )
    trial = db.get(Trial, trial_id)
    if assigned is None or trial is None:
        raise HTTPException(404, f"trial {trial_id} is not in your annotation queue")
    return trial


AssignedTrial = Annotated[Trial, Depends(assigned_trial)]


@router.get("/annotate", response_class=HTMLResponse)
def queue(request: Request, db: DbSession, annotations: AnnotationsDep, annotator: AnnotatorId) -> HTMLResponse:
    rows = db.execute(
        select(Trial.id, Trial.maze)
        .join(AnnotationAssignment, AnnotationAssignment.trial_id == Trial.id)
        .where(AnnotationAssignment.annotator_id == annotator)
        .order_by(Trial.id)
    ).all()
    states = annotations.states(r.id for r in rows)
    items = [{"id": r.id, "maze": r.maze, "annotation": states[r.id].by_annotator.get(annotator)} for r in rows]
    done = sum(1 for i in items if i["annotation"] is not None and i["annotation"].submitted)
    return render(request, "annotate/queue.html", items=items, done=done)


def study_tags(files: StudyFiles, trial: Trial) -> list[str] | None:
    """The free tags the trial's study defines; None where it has no study file (any tag goes)."""
    if trial.study is None:
        return None
    try:
        return files.load(trial.study).annotation_tags
    except LookupError:
        return None


@router.get("/annotate/trials/{trial_id}", response_class=HTMLResponse)
def annotate_trial(
    request: Request,
    trial: AssignedTrial,
    annotations: AnnotationsDep,
    log: LogDep,
    files: StudyFilesDep,
    annotator: AnnotatorId,
) -> HTMLResponse:
    events = log.load(trial.id)
    mine = annotations.state(trial.id).by_annotator.get(annotator)
    return render(
        request,
        "annotate/trial.html",
        study_tags=study_tags(files, trial),
        trial=trial,
        messages=messages(events),
        estimates={e.after_message: e for e in estimates(events)},
        mine=mine,
        phenomena=list(TITLES.items()),
        titles=TITLES,
    )


@router.get("/annotate/trials/{trial_id}/replay.json")
def annotate_replay(trial: AssignedTrial, log: LogDep) -> dict[str, Any]:
    """The trial's log as the replay page reads it (`static/replay.js`), without the team."""
    return {
        "trial": {"id": trial.id, "maze": trial.maze, "targets": trial.targets, "phase": trial.phase},
        "events": replay_events(log.load(trial.id), f"/annotate/trials/{trial.id}"),
    }


@router.get("/annotate/trials/{trial_id}/frames/{frame_id}.jpg")
def annotate_frame(trial: AssignedTrial, frame_id: int, db: DbSession, settings: SettingsDep) -> FileResponse:
    return frame_file(db, settings, trial.id, frame_id)


@router.get("/annotate/trials/{trial_id}/map.png")
def annotate_map(trial: AssignedTrial, mazes: MazesDep) -> Response:
    return Response(
        mazes.full_map_png(trial.maze), media_type="image/png", headers={"Cache-Control": "private, max-age=3600"}
    )


@router.post("/annotate/trials/{trial_id}")
def save(
    trial: AssignedTrial,
    annotations: AnnotationsDep,
    clock: ClockDep,
    log: LogDep,
    files: StudyFilesDep,
    annotator: AnnotatorId,
    action: Annotated[str, Form()],
    cut: Annotated[int | None, Form()] = None,
    tag: Annotated[str, Form(max_length=60)] = "",
    free_tag: Annotated[str, Form(max_length=60)] = "",
    anchor: Annotated[list[int] | None, Form()] = None,
) -> RedirectResponse:
    """One change from the trial's form: `cut` (the radio checked), `tag` (the phenomenon or free
    tag, anchored to the checked messages; none checked withdraws it) or `submit`."""
    said = len(messages(log.load(trial.id)))
    anchors = sorted(set(anchor or []))
    event: AnnotationEventModel
    if action == "cut":
        if cut is None or not 0 <= cut <= said:
            raise HTTPException(422, f"pick the message after which the robot was localized (0 to {said})")
        event = CutMarked(message=cut)
    elif action == "tag":
        name = free_tag.strip().lower() or tag
        if not name:
            raise HTTPException(422, "pick a phenomenon or write a tag")
        allowed = study_tags(files, trial)
        if allowed is not None and name not in allowed and name not in TITLES:
            known = ", ".join(allowed) or "none"
            raise HTTPException(
                422,
                f"{name!r} is not a tag of study {trial.study!r} (its tags: {known}); the experimenter adds tags in the study file",
            )
        if any(not 1 <= m <= said for m in anchors):
            raise HTTPException(422, f"anchors must be message numbers from 1 to {said}")
        event = Tagged(tag=name, messages=anchors)
    elif action == "submit":
        event = Submitted()
    else:
        raise HTTPException(422, f"unknown action {action!r}: cut, tag or submit")
    annotations.append(trial.id, annotator, event, clock.now_ns())
    target = "/annotate" if action == "submit" else f"/annotate/trials/{trial.id}"
    return RedirectResponse(target, status_code=303)


@router.post("/annotate/logout")
def logout(
    request: Request, sessions: AnnotatorSessionsDep, login: Annotated[Login | None, Depends(annotator_login)]
) -> RedirectResponse:
    if login is not None:
        sessions.end(login)
    return logged_out(request, ANNOTATOR_COOKIE)


@router.get("/experimenter/annotation", response_class=HTMLResponse)
def agreement_page(
    request: Request,
    db: DbSession,
    annotations: AnnotationsDep,
    _: ExperimenterId,
    study: str = "",
    created: str = "",
) -> HTMLResponse:
    """Agreement between the study's annotators, the disagreements to adjudicate, and the form
    that makes an annotator's account."""
    result = study_agreement(db, annotations, study) if study else None
    annotators = sorted(db.scalars(select(Experimenter.name).where(Experimenter.role == AccountRole.ANNOTATOR)).all())
    return render(
        request,
        "annotate/agreement.html",
        study=study,
        result=result,
        titles=TITLES,
        answer=answer_word,  # a tag's answers as yes/no, as its adjudication asks
        annotators=annotators,
        created=created,
    )


@router.post("/experimenter/annotators")
def add_annotator(
    db: DbSession,
    _: ExperimenterId,
    name: Annotated[str, Form(max_length=80)],
    password: Annotated[str, Form(max_length=200)],
    study: Annotated[str, Form(max_length=80)] = "",
) -> RedirectResponse:
    """An annotator account (as `robotslang admin create NAME --role annotator`)."""
    try:
        with db.begin():
            create_account(db, name, password, AccountRole.ANNOTATOR)
    except AccountError as err:
        raise HTTPException(422, str(err)) from None
    return RedirectResponse(f"/experimenter/annotation?study={quote(study)}&created={quote(name.strip())}", 303)


@router.post("/experimenter/annotation/adjudicate")
def adjudicate(
    db: DbSession,
    annotations: AnnotationsDep,
    clock: ClockDep,
    experimenter: ExperimenterId,
    trial_id: Annotated[int, Form()],
    item: Annotated[str, Form(max_length=64)],
    value: Annotated[str, Form(max_length=16)],
    study: Annotated[str, Form(max_length=80)] = "",
) -> RedirectResponse:
    """The experimenter's value for a disagreement, stored beside both annotators' (theirs stay)."""
    if db.get(Trial, trial_id) is None:
        raise HTTPException(404, f"trial {trial_id} does not exist")
    decided: int | bool
    if item == "cut":
        if not value.isdigit():
            raise HTTPException(422, "the adjudicated cut is a message number")
        decided = int(value)
    elif value in ("yes", "no"):
        decided = value == "yes"
    else:
        raise HTTPException(422, "a tag is adjudicated yes or no")
    annotations.append(trial_id, experimenter, Adjudicated(item=item, value=decided), clock.now_ns())
    return RedirectResponse(f"/experimenter/annotation?study={study}", status_code=303)

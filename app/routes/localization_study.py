"""LDH human studies: the experimenter's pages (create, invite, results, export) and the
participant's page behind a signed study link (one instance at a time, truth only at the end)."""

from __future__ import annotations

import csv
import io
from typing import Annotated
from urllib.parse import quote

from fastapi import APIRouter, Depends, Form, HTTPException, Request
from fastapi.responses import HTMLResponse, JSONResponse, RedirectResponse, Response
from pydantic import BaseModel, ConfigDict

from app.db.models import LDHStudy
from app.deps import ExperimenterId, LocalizationStudiesDep, StudyTokensDep, experimenter_id
from app.guard import csrf_protect
from app.i18n import Language
from app.localization_study import CSV_COLUMNS, LocalizationStudyError
from app.security import InvalidToken, StudyPass
from app.web import render

router = APIRouter()
studies_router = APIRouter(prefix="/experimenter/ldh", dependencies=[Depends(experimenter_id), Depends(csrf_protect)])


def existing_study(study_id: int, studies: LocalizationStudiesDep) -> LDHStudy:
    try:
        return studies.study(study_id)
    except LookupError as err:
        raise HTTPException(404, str(err)) from None


ExistingStudy = Annotated[LDHStudy, Depends(existing_study)]


def _back(study_id: int | None = None, error: str | None = None) -> RedirectResponse:
    page = "/experimenter/ldh" + (f"/{study_id}" if study_id is not None else "")
    return RedirectResponse(page + (f"?error={quote(error)}" if error else ""), status_code=303)


# -- the experimenter -----------------------------------------------------------------------
@studies_router.get("", response_class=HTMLResponse)
def study_list(request: Request, s: LocalizationStudiesDep, error: str | None = None) -> HTMLResponse:
    return render(
        request,
        "ldh_studies.html",
        studies=s.all_studies(),
        default_source=s.default_source(),
        languages=list(Language),
        error=error,
    )


@studies_router.post("")
def create_study(
    studies: LocalizationStudiesDep,
    experimenter: ExperimenterId,
    name: str = Form(max_length=80),
    source: str = Form(max_length=1000),
    split: str = Form("val_seen"),
    variant: str = Form("prefix"),
    limit: int | None = Form(None),
    language: Language = Form(Language.en),
) -> RedirectResponse:
    try:
        study_id = studies.create(experimenter, name, source, split, variant, limit, language)
    except LocalizationStudyError as err:
        return _back(error=str(err))
    return _back(study_id)


@studies_router.post("/{study_id}/participants")
def invite(studies: LocalizationStudiesDep, study: ExistingStudy, name: str = Form(max_length=80)) -> RedirectResponse:
    try:
        studies.invite(study.id, name)
    except LocalizationStudyError as err:
        return _back(study.id, str(err))
    return _back(study.id)


@studies_router.get("/{study_id}", response_class=HTMLResponse)
def study_page(
    request: Request, s: LocalizationStudiesDep, tokens: StudyTokensDep, study: ExistingStudy, error: str | None = None
) -> HTMLResponse:
    links = {
        p.id: str(request.url_for("ldh_participant", token=tokens.issue(study.id, p.id)))
        for p in s.participants(study.id)
    }
    return render(request, "ldh_study.html", study=study, results=s.results(study.id), links=links, error=error)


@studies_router.get("/{study_id}/export.json")
def export_json(studies: LocalizationStudiesDep, study: ExistingStudy) -> JSONResponse:
    return JSONResponse(
        studies.results(study.id),
        headers={"Content-Disposition": f'attachment; filename="ldh-study-{study.id}.json"'},
    )


@studies_router.get("/{study_id}/export.csv")
def export_csv(studies: LocalizationStudiesDep, study: ExistingStudy) -> Response:
    out = io.StringIO()
    writer = csv.DictWriter(out, fieldnames=CSV_COLUMNS, extrasaction="ignore")
    writer.writeheader()
    writer.writerows(studies.results(study.id)["answers"])
    return Response(
        out.getvalue(),
        media_type="text/csv",
        headers={"Content-Disposition": f'attachment; filename="ldh-study-{study.id}.csv"'},
    )


# -- the participant --------------------------------------------------------------------------
def study_pass(request: Request, token: str, tokens: StudyTokensDep, studies: LocalizationStudiesDep) -> StudyPass:
    """The study and participant a link opens, its pages in the study's language; 403 for a forged
    link or one naming another study's participant."""
    try:
        granted = tokens.verify(token)
        studies.participant(granted.study_id, granted.participant_id)
    except (InvalidToken, LookupError) as err:
        raise HTTPException(403, str(err)) from None
    request.state.language = Language(studies.study(granted.study_id).language)
    return granted


Granted = Annotated[StudyPass, Depends(study_pass)]


@router.get("/ldh/{token}", response_class=HTMLResponse, name="ldh_participant")
def participant_page(request: Request, token: str, granted: Granted, s: LocalizationStudiesDep) -> HTMLResponse:
    study, instances = s.study(granted.study_id), s.instances(granted.study_id)
    position = s.next_position(granted.study_id, granted.participant_id)
    if position is None:  # done: now, and only now, their answers beside the truth
        answers = s.answers(granted.study_id, granted.participant_id)
        return render(request, "ldh_done.html", study=study, answers=answers, instances=instances)
    inst = instances[position]
    landmarks = s.benchmark(study.source).maze(inst.run).objects
    return render(
        request,
        "ldh_answer.html",
        token=token,
        study=study,
        position=position,
        total=len(instances),
        dialog=inst.dialog,
        landmarks=sorted(landmarks),
    )


@router.get("/ldh/{token}/map/{position}.png")
def participant_map(granted: Granted, s: LocalizationStudiesDep, position: int) -> Response:
    instances = s.instances(granted.study_id)
    if not 0 <= position < len(instances):
        raise HTTPException(404, f"the study has no instance {position + 1}")
    return Response(
        s.map_png(s.study(granted.study_id).source, instances[position].run),
        media_type="image/png",
        headers={"Cache-Control": "private, max-age=3600"},
    )


class Mark(BaseModel):
    """Where the participant says the robot is (metres, table frame) and, if dragged, its heading."""

    model_config = ConfigDict(extra="forbid")
    position: int
    x: float
    y: float
    heading: float | None = None


@router.post("/ldh/{token}/answers", dependencies=[Depends(csrf_protect)])
def submit(granted: Granted, s: LocalizationStudiesDep, mark: Mark) -> dict[str, int | None]:
    """Record one answer. The reply says only that it was taken (never the score or the truth)."""
    try:
        answer = s.answer(granted.study_id, granted.participant_id, mark.position, mark.x, mark.y, mark.heading)
    except LocalizationStudyError as err:
        raise HTTPException(409, err.args[0]) from None  # a `Text`: said in the study's language
    return {"recorded": answer.seq, "next": s.next_position(granted.study_id, granted.participant_id)}


router.include_router(studies_router)

"""What every page route shares: rendering a template, the error page, a trial or 404, and a
trial's log and frames as the replay pages (the experimenter's and the annotator's) serve them.

Routes import these from here, never from another route module.
"""

from __future__ import annotations

from typing import Any

from fastapi import HTTPException, Request
from fastapi.responses import FileResponse, HTMLResponse
from sqlalchemy import select
from sqlalchemy.orm import Session

from app.db.models import Frame, Trial
from app.deps import get_templates
from app.i18n import Text, language_of, said
from app.settings import Settings
from app.study.config import StudyFiles
from sim.trial import events as ev

ADVICE = {
    403: (
        Text("Not allowed"),
        Text(
            "This page or action is not open to you. If you followed a join link, it may be "
            "mistyped or belong to another trial. Ask your experimenter for a new join link."
        ),
    ),
    404: (
        Text("Page not found"),
        Text("There is nothing at this address. Check the link, or start from the home page."),
    ),
    409: (
        Text("Not possible now"),
        Text("That cannot be done in the trial's present state. Go back and reload the page."),
    ),
    422: (
        Text("That did not work"),
        Text("Something in the request was not filled in as expected. Go back and try again."),
    ),
}
SOMETHING_WRONG = (Text("Something went wrong"), Text("Go back and try again."))


def wants_html(request: Request) -> bool:
    """A browser following a link or submitting a form, not a script or a fetch() for JSON."""
    return "text/html" in request.headers.get("accept", "")


def error_page(request: Request, status_code: int, detail: object) -> HTMLResponse:
    """A page saying what went wrong and what to do, in the request's language (`app.i18n`)."""
    lang = language_of(request)
    heading, advice = (said(t, lang) for t in ADVICE.get(status_code, SOMETHING_WRONG))
    # A participant's study page: back into the study's way, no link out of it.
    _, first, *rest = request.url.path.split("/")
    study = f"/study/{rest[0]}" if first == "study" and rest else None
    response = render(
        request,
        "error.html",
        status_code=status_code,
        heading=heading,
        advice=advice,
        detail=said(detail, lang) if detail else None,
        study=study,
        in_flow=study is not None,
    )
    response.status_code = status_code
    return response


def render(request: Request, template: str, **context: Any) -> HTMLResponse:
    response: HTMLResponse = get_templates(request).TemplateResponse(request, template, context)
    return response


def trial_or_404(db: Session, trial_id: int) -> Trial:
    trial = db.get(Trial, trial_id)
    if trial is None:
        raise HTTPException(404, f"trial {trial_id} does not exist")
    return trial


def speak_study(request: Request, files: StudyFiles, study: str | None) -> None:
    """The request's pages and messages in the study's language (`app.i18n`), where it is a study's."""
    if study:
        request.state.language = files.language(study)


def over_reason(phase: str) -> Text | None:
    """Why a join link of a trial in `phase` opens nothing any more; None while the trial runs."""
    match phase:
        case "finished":
            return Text("this trial is over: thank you for taking part")
        case "aborted":
            return Text("this trial was stopped: ask the experimenter what comes next")
    return None


def replay_events(log: list[ev.LoggedEvent], base: str) -> list[dict[str, Any]]:
    """The log as the replay page reads it: each frame's file replaced by its URL under `base`."""
    events = []
    for e in log:
        payload = dict(e.payload)
        if e.is_(ev.FrameRecorded):
            payload.pop("path", None)
            payload["url"] = f"{base}/frames/{payload['frame_id']}.jpg"
        events.append({"seq": e.seq, "kind": e.kind, "t_ns": e.t_ns, "payload": payload})
    return events


def frame_file(db: Session, settings: Settings, trial_id: int, frame_id: int) -> FileResponse:
    rel = db.scalar(select(Frame.path).where(Frame.trial_id == trial_id, Frame.seq == frame_id))
    if rel is None:
        raise HTTPException(404, f"trial {trial_id} has no frame {frame_id}")
    path = settings.frames_dir / rel
    if not path.is_file():
        raise HTTPException(404, f"frame {frame_id} of trial {trial_id}: file {rel} is missing")
    return FileResponse(path, media_type="image/jpeg", headers={"Cache-Control": "private, max-age=86400"})

"""What every page route shares: rendering a template, the error page, and a trial or 404.

Routes import these from here, never from another route module.
"""

from __future__ import annotations

from typing import Any

from fastapi import HTTPException, Request
from fastapi.responses import HTMLResponse
from sqlalchemy.orm import Session

from app.db.models import Trial
from app.deps import get_templates

ADVICE = {
    403: (
        "Not allowed",
        "This page or action is not open to you. If you followed a join link, it may be "
        "mistyped or belong to another trial. Ask your experimenter for a new join link.",
    ),
    404: ("Page not found", "There is nothing at this address. Check the link, or start from the home page."),
    409: ("Not possible now", "That cannot be done in the trial's present state. Go back and reload the page."),
    422: ("That did not work", "Something in the request was not filled in as expected. Go back and try again."),
}


def wants_html(request: Request) -> bool:
    """A browser following a link or submitting a form, not a script or a fetch() for JSON."""
    return "text/html" in request.headers.get("accept", "")


def error_page(request: Request, status_code: int, detail: str | None) -> HTMLResponse:
    heading, advice = ADVICE.get(status_code, ("Something went wrong", "Go back and try again."))
    response = render(request, "error.html", status_code=status_code, heading=heading, advice=advice, detail=detail)
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


def over_reason(trial: Trial) -> str | None:
    """Why a join link of this trial opens nothing any more; None while the trial runs."""
    match trial.phase:
        case "finished":
            return "this trial is over: thank you for taking part"
        case "aborted":
            return "this trial was stopped: ask the experimenter what comes next"
    return None

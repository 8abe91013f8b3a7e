"""Public pages: home (log in), the seat pages behind join links, and the leaderboard."""

from __future__ import annotations

from fastapi import APIRouter, Depends, Form, HTTPException, Request
from fastapi.responses import HTMLResponse, RedirectResponse, Response

from app.annotation.access import annotator_sessions
from app.db.models import Experimenter, Trial
from app.guard import csrf_protect, current_login
from app.leaderboard import agent_standings, standings
from app.login import TooManyAttempts
from app.security import ANNOTATOR_COOKIE, SESSION_COOKIE, SESSION_MAX_AGE_S, ExpiredLink, InvalidToken, Seat
from app.trial.state import fold

router = APIRouter()


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


def render(request: Request, template: str, **context) -> HTMLResponse:
    return request.app.state.templates.TemplateResponse(request, template, context)


def trial_or_404(request: Request, trial_id: int) -> Trial:
    with request.app.state.services.db() as db:
        trial = db.get(Trial, trial_id)
    if trial is None:
        raise HTTPException(404, f"trial {trial_id} does not exist")
    return trial


class ClosedLink(HTTPException):
    """A genuine join link that opens nothing any more: expired, or its trial is over (410 Gone)."""

    def __init__(self, reason: str) -> None:
        super().__init__(410, reason)


def seat_of(request: Request, token: str) -> tuple[Seat, Trial]:
    """The seat a join link opens and its trial; 403 for a forged link, `ClosedLink` for a closed one."""
    try:
        seat = request.app.state.services.seats.admit(token)
    except ExpiredLink as err:
        raise ClosedLink(str(err)) from None
    except InvalidToken as err:
        raise HTTPException(403, str(err)) from None
    trial = trial_or_404(request, seat.trial_id)
    if (reason := over_reason(trial)) is not None:
        raise ClosedLink(reason)
    return seat, trial


def over_reason(trial: Trial) -> str | None:
    """Why a join link of this trial opens nothing any more; None while the trial runs."""
    match trial.phase:
        case "finished":
            return "this trial is over: thank you for taking part"
        case "aborted":
            return "this trial was stopped: ask the experimenter what comes next"
    return None


@router.get("/", response_class=HTMLResponse)
def home(request: Request):
    if current_login(request) is not None:
        return RedirectResponse("/experimenter", status_code=303)
    if request.cookies.get(ANNOTATOR_COOKIE) and annotator_sessions(request.app.state.services).verify(
        request.cookies[ANNOTATOR_COOKIE]
    ):
        return RedirectResponse("/annotate", status_code=303)
    return render(request, "home.html", error=None, join_error=None)


@router.get("/join")
def join(request: Request, link: str = ""):
    """A pasted join link (or its token) to the seat's page."""
    token = link.strip().rstrip("/").rsplit("/", 1)[-1]
    try:
        request.app.state.services.seats.verify(token)
    except InvalidToken:
        return render(request, "home.html", error=None, join_error="that is not a valid join link")
    return RedirectResponse(f"/play/{token}", status_code=303)


@router.post("/login", dependencies=[Depends(csrf_protect)])
async def login(request: Request, name: str = Form(max_length=80), password: str = Form(max_length=200)):
    services = request.app.state.services
    try:
        user_id = await services.logins.authenticate(name, password, request.client.host if request.client else "")
    except TooManyAttempts as err:
        response = render(request, "home.html", error=str(err), join_error=None)
        response.status_code, response.headers["Retry-After"] = 429, str(err.retry_after_s)
        return response
    if user_id is None:
        response = render(request, "home.html", error="unknown name or wrong password", join_error=None)
        response.status_code = 401
        return response
    annotator = annotator_sessions(services)
    with services.db() as db:
        is_annotator = db.get(Experimenter, user_id).role == annotator.role
    sessions, cookie = (annotator, ANNOTATOR_COOKIE) if is_annotator else (services.sessions, SESSION_COOKIE)
    redirect = RedirectResponse("/annotate" if is_annotator else "/experimenter", status_code=303)
    redirect.set_cookie(
        cookie,
        sessions.issue(user_id),
        max_age=SESSION_MAX_AGE_S,
        httponly=True,
        samesite="strict",
        secure=request.url.scheme == "https",
    )
    return redirect


@router.post("/logout", dependencies=[Depends(csrf_protect)])
def logout(request: Request):
    login = current_login(request)
    if login is not None:
        request.app.state.services.sessions.end(login)
        request.app.state.services.login_sockets.end(login)
    response = RedirectResponse("/", status_code=303)
    response.delete_cookie(SESSION_COOKIE)
    return response


@router.get("/leaderboard", response_class=HTMLResponse)
def leaderboard(request: Request):
    services = request.app.state.services
    with services.db() as db:
        teams = standings(db, services.settings.move_penalty_s)
        agents = agent_standings(db, services.settings.move_penalty_s)
    is_experimenter = current_login(request) is not None
    return render(
        request,
        "leaderboard.html",
        rows=teams,
        agents=agents,
        penalty=services.settings.move_penalty_s,
        experimenter=is_experimenter,
    )


@router.get("/play/{token}", response_class=HTMLResponse)
def play(request: Request, token: str):
    try:
        seat, trial = seat_of(request, token)
    except ClosedLink as closed:
        response = render(request, "link_closed.html", reason=closed.detail)
        response.status_code = 410
        return response
    if seat.role == "commander":  # where the landmarks are: the Commander's to know, never the Driver's
        landmarks = request.app.state.services.mazes.landmarks(trial.maze)
        return render(request, "commander.html", token=token, trial=trial, landmarks=landmarks)
    return render(request, f"{seat.role}.html", token=token, trial=trial)


@router.get("/play/{token}/map.png")
def commander_map(request: Request, token: str):
    """The map with the three landmarks, for the Commander alone."""
    seat, trial = seat_of(request, token)
    if seat.role != "commander":
        raise HTTPException(403, "only the Commander sees the map")
    return Response(
        request.app.state.services.mazes.map_png(trial.maze),
        media_type="image/png",
        headers={"Cache-Control": "private, max-age=3600"},
    )


@router.get("/play/{token}/target/{index}.jpg")
def target_image(request: Request, token: str, index: int):
    """The image of a target the Commander has reached or is looking for (never a later one)."""
    seat, trial = seat_of(request, token)
    if seat.role != "commander":
        raise HTTPException(403, "only the Commander sees the target images")
    services = request.app.state.services
    runtime = services.hub.peek(trial.id)  # None where the trial runs in another process
    reached = (runtime.state if runtime is not None else fold(services.log.load(trial.id))).target_index
    if not 0 <= index < len(trial.targets) or index > reached:
        raise HTTPException(404, f"target {index} is not available")
    return Response(
        services.mazes.target_jpeg(trial.maze, trial.targets[index]),
        media_type="image/jpeg",
        headers={"Cache-Control": "private, max-age=3600"},
    )

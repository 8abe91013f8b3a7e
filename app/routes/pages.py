"""Public pages: home (log in), the seat pages behind join links, and the leaderboard."""

from __future__ import annotations

from urllib.parse import quote

from fastapi import APIRouter, Depends, Form, HTTPException, Request
from fastapi.responses import HTMLResponse, RedirectResponse, Response
from sqlalchemy.orm import Session

from app.cookies import logged_out, read_cookie, set_cookie
from app.db.models import Experimenter, Trial
from app.deps import (
    AnnotatorSessionsDep,
    CurrentLogin,
    DbSession,
    HubDep,
    LogDep,
    LoginsDep,
    LoginSocketsDep,
    MazesDep,
    SeatTokensDep,
    SessionsDep,
    SettingsDep,
    StudyFilesDep,
)
from app.guard import csrf_protect
from app.i18n import language_of, said
from app.leaderboard import agent_standings, pair_standings, standings
from app.login import TooManyAttempts
from app.security import (
    ANNOTATOR_COOKIE,
    SESSION_COOKIE,
    SESSION_MAX_AGE_S,
    ExpiredLink,
    InvalidToken,
    Seat,
    SeatTokens,
)
from app.study.config import StudyConfigError
from app.study.lobby import PRACTICE_REASON
from app.web import over_reason, render, speak_study, trial_or_404
from sim.trial.state import fold

router = APIRouter()


class ClosedLink(HTTPException):
    """A genuine join link that opens nothing any more: expired, or its trial is over (410 Gone)."""

    def __init__(self, reason: str, after_url: str | None = None, study: str | None = None) -> None:
        super().__init__(410, reason)
        self.after_url, self.study = after_url, study


def after_trial_url(trial: Trial) -> str | None:
    """Where a study's participant goes on from a seat once its trial is over (questionnaire or lobby)."""
    return f"/study/{quote(trial.study)}/trials/{trial.id}/next" if trial.study else None


def seat_of(seats: SeatTokens, db: Session, token: str) -> tuple[Seat, Trial]:
    """The seat a join link opens and its trial; 403 for a forged link, `ClosedLink` for a closed one."""
    try:
        seat = seats.admit(token)
    except ExpiredLink as err:  # genuine, so its trial says whose language the page speaks
        expired = db.get(Trial, seats.verify(token).trial_id)
        raise ClosedLink(err.args[0], study=expired.study if expired else None) from None
    except InvalidToken as err:
        raise HTTPException(403, str(err)) from None
    trial = trial_or_404(db, seat.trial_id)
    if (reason := over_reason(trial.phase)) is not None:
        raise ClosedLink(reason, after_trial_url(trial), trial.study)
    return seat, trial


@router.get("/", response_class=HTMLResponse)
def home(request: Request, login: CurrentLogin, annotators: AnnotatorSessionsDep) -> Response:
    if login is not None:
        return RedirectResponse("/experimenter", status_code=303)
    if annotators.verify(read_cookie(request, ANNOTATOR_COOKIE)) is not None:
        return RedirectResponse("/annotate", status_code=303)
    return render(request, "home.html", error=None, join_error=None)


@router.get("/join")
def join(request: Request, seats: SeatTokensDep, link: str = "") -> Response:
    """A pasted join link (or its token) to the seat's page."""
    token = link.strip().rstrip("/").rsplit("/", 1)[-1]
    try:
        seats.verify(token)
    except InvalidToken:
        return render(request, "home.html", error=None, join_error="that is not a valid join link")
    return RedirectResponse(f"/play/{token}", status_code=303)


@router.post("/login", dependencies=[Depends(csrf_protect)])
async def login(
    request: Request,
    logins: LoginsDep,
    sessions: SessionsDep,
    annotators: AnnotatorSessionsDep,
    db: DbSession,
    name: str = Form(max_length=80),
    password: str = Form(max_length=200),
) -> Response:
    try:
        user_id = await logins.authenticate(name, password, request.client.host if request.client else "")
    except TooManyAttempts as err:
        response = render(request, "home.html", error=str(err), join_error=None)
        response.status_code, response.headers["Retry-After"] = 429, str(err.retry_after_s)
        return response
    if user_id is None:
        response = render(request, "home.html", error="unknown name or wrong password", join_error=None)
        response.status_code = 401
        return response
    account = db.get(Experimenter, user_id)
    is_annotator = account is not None and account.role == annotators.role
    sessions, cookie = (annotators, ANNOTATOR_COOKIE) if is_annotator else (sessions, SESSION_COOKIE)
    redirect = RedirectResponse("/annotate" if is_annotator else "/experimenter", status_code=303)
    set_cookie(redirect, request, cookie, sessions.issue(user_id), samesite="strict", max_age=SESSION_MAX_AGE_S)
    return redirect


@router.post("/logout", dependencies=[Depends(csrf_protect)])
def logout(
    request: Request, login: CurrentLogin, sessions: SessionsDep, login_sockets: LoginSocketsDep
) -> RedirectResponse:
    if login is not None:
        sessions.end(login)
        login_sockets.end(login)
    return logged_out(request, SESSION_COOKIE)


@router.get("/leaderboard", response_class=HTMLResponse)
def leaderboard(
    request: Request,
    db: DbSession,
    settings: SettingsDep,
    login: CurrentLogin,
    files: StudyFilesDep,
    study: str | None = None,
) -> HTMLResponse:
    """Every finished trial, or one study's (`?study=NAME`, scored with the study's move penalty
    where its file sets one)."""
    penalty = settings.move_penalty_s
    if study:
        try:
            penalty = files.move_penalty_s(study, penalty)
        except StudyConfigError as err:
            raise HTTPException(500, f"study {study!r}: {err}") from None
    teams = standings(db, penalty, study or None)
    agents = agent_standings(db, penalty, study or None)
    pairs = pair_standings(db, penalty, study or None)
    is_experimenter = login is not None
    return render(
        request,
        "leaderboard.html",
        rows=teams,
        agents=agents,
        pairs=pairs,
        penalty=penalty,
        study=study or None,
        experimenter=is_experimenter,
    )


@router.get("/play/{token}", response_class=HTMLResponse)
def play(
    request: Request,
    token: str,
    seats: SeatTokensDep,
    db: DbSession,
    log: LogDep,
    mazes: MazesDep,
    settings: SettingsDep,
    files: StudyFilesDep,
) -> HTMLResponse:
    try:
        seat, trial = seat_of(seats, db, token)
    except ClosedLink as closed:
        speak_study(request, files, closed.study)
        reason = said(closed.detail, language_of(request))
        response = render(
            request, "link_closed.html", reason=reason, after_url=closed.after_url, in_flow=bool(closed.after_url)
        )
        response.status_code = 410
        return response
    speak_study(request, files, trial.study)
    # A study's seat: no link out of the study's way; its practice says so, and when it stops.
    seat_page = {
        "token": token,
        "trial": trial,
        "after_url": after_trial_url(trial),
        "in_flow": trial.study is not None,
        "practice": trial.excluded_reason == PRACTICE_REASON,
        "time_cap_s": fold(log.load(trial.id)).time_cap_s,
    }
    if seat.role == "commander":  # where the landmarks are: the Commander's to know, never the Driver's
        landmarks, walls = mazes.landmarks(trial.maze), mazes.map_walls(trial.maze)
        return render(request, "commander.html", landmarks=landmarks, walls=walls, **seat_page)
    # The Driver's page sends a press no sooner than the server takes a move (`min_move_interval_s`).
    return render(request, f"{seat.role}.html", min_move_interval_s=settings.min_move_interval_s, **seat_page)


@router.get("/play/{token}/map.png")
def commander_map(token: str, seats: SeatTokensDep, db: DbSession, mazes: MazesDep) -> Response:
    """The map with the three landmarks, for the Commander alone."""
    seat, trial = seat_of(seats, db, token)
    if seat.role != "commander":
        raise HTTPException(403, "only the Commander sees the map")
    return Response(
        mazes.map_png(trial.maze),
        media_type="image/png",
        headers={"Cache-Control": "private, max-age=3600"},
    )


@router.get("/play/{token}/target/{index}.jpg")
def target_image(
    token: str, index: int, seats: SeatTokensDep, db: DbSession, hub: HubDep, log: LogDep, mazes: MazesDep
) -> Response:
    """The image of a target the Commander has reached or is looking for (never a later one)."""
    seat, trial = seat_of(seats, db, token)
    if seat.role != "commander":
        raise HTTPException(403, "only the Commander sees the target images")
    runtime = hub.peek(trial.id)  # None where the trial runs in another process
    reached = (runtime.state if runtime is not None else fold(log.load(trial.id))).target_index
    if not 0 <= index < len(trial.targets) or index > reached:
        raise HTTPException(404, f"target {index} is not available")
    return Response(
        mazes.target_jpeg(trial.maze, trial.targets[index]),
        media_type="image/jpeg",
        headers={"Cache-Control": "private, max-age=3600"},
    )

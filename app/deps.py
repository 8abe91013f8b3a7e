"""Typed request dependencies: what a route may ask of the server, as `Annotated` parameters.

A route names what it needs (`db: DbSession`, `mazes: MazesDep`, `_: ExperimenterId`) instead of
reading `request.app.state`; most read one part of `Services` (`_part`).
Works for HTTP routes and websockets alike (both are an `HTTPConnection`). Helpers called outside
a route's parameters (a template's context, a middleware's check) use `get_services`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Annotated, TypeVar

from fastapi import Depends
from fastapi.templating import Jinja2Templates
from sqlalchemy.orm import Session, sessionmaker
from starlette.requests import HTTPConnection

from app.annotation.log import AnnotationLog
from app.clock import ServerClock
from app.cookies import read_cookie
from app.localization_study import LocalizationStudies
from app.login import LoginGuard
from app.login_sockets import LoginSockets
from app.mazes import Mazes
from app.rover.links import RobotLinks
from app.seats.registry import AgentParts
from app.security import SESSION_COOKIE, CsrfTokens, Login, SeatTokens, Sessions, StudyTokens
from app.services import Services
from app.settings import Settings
from app.study.config import StudyFiles
from app.study.signups import SignupLimits
from app.study.webhook import StudyWebhooks
from app.trial.hub import TrialHub
from app.trial.log import EventLog

_Part = TypeVar("_Part")


class LoginRequired(Exception):
    """Raised by `experimenter_id` for anonymous requests; create_app answers with a redirect home."""


def get_services(conn: HTTPConnection) -> Services:
    services: Services = conn.app.state.services
    return services


def _part(read: Callable[[Services], _Part]) -> Callable[[HTTPConnection], _Part]:
    """A dependency on one part of the server's services."""

    def part(conn: HTTPConnection) -> _Part:
        return read(get_services(conn))

    return part


def get_db(conn: HTTPConnection) -> Iterator[Session]:
    """A session for this request, closed after it; write inside `with db.begin():`."""
    with get_services(conn).db() as db:
        yield db


def get_templates(conn: HTTPConnection) -> Jinja2Templates:
    templates: Jinja2Templates = conn.app.state.templates
    return templates


def current_login(conn: HTTPConnection) -> Login | None:
    """The experimenter logged in with this request's cookie (looked up once per request)."""
    if not hasattr(conn.state, "login"):
        conn.state.login = get_services(conn).sessions.verify(read_cookie(conn, SESSION_COOKIE))
    login: Login | None = conn.state.login
    return login


def experimenter_id(conn: HTTPConnection) -> int:
    """The logged-in experimenter's id; anonymous requests are sent to the login page."""
    login = current_login(conn)
    if login is None:
        raise LoginRequired()
    return login.experimenter_id


SettingsDep = Annotated[Settings, Depends(_part(lambda s: s.settings))]
DbSession = Annotated[Session, Depends(get_db)]
# Sessions to open as needed: for a socket, which must not hold one for its whole life.
DbFactory = Annotated[sessionmaker[Session], Depends(_part(lambda s: s.db))]
LogDep = Annotated[EventLog, Depends(_part(lambda s: s.log))]
HubDep = Annotated[TrialHub, Depends(_part(lambda s: s.hub))]
MazesDep = Annotated[Mazes, Depends(_part(lambda s: s.mazes))]
SeatTokensDep = Annotated[SeatTokens, Depends(_part(lambda s: s.seats))]
RobotLinksDep = Annotated[RobotLinks, Depends(_part(lambda s: s.robots))]
AgentsDep = Annotated[AgentParts, Depends(_part(lambda s: s.agents))]
ClockDep = Annotated[ServerClock, Depends(_part(lambda s: s.clock))]
SessionsDep = Annotated[Sessions, Depends(_part(lambda s: s.sessions))]
AnnotationsDep = Annotated[AnnotationLog, Depends(_part(lambda s: s.annotations))]
StudyFilesDep = Annotated[StudyFiles, Depends(_part(lambda s: StudyFiles.of(s.settings.data_dir)))]
WebhooksDep = Annotated[StudyWebhooks, Depends(_part(lambda s: s.webhooks))]
AnnotatorSessionsDep = Annotated[Sessions, Depends(_part(lambda s: s.annotator_sessions))]
CsrfDep = Annotated[CsrfTokens, Depends(_part(lambda s: s.csrf))]
LoginsDep = Annotated[LoginGuard, Depends(_part(lambda s: s.logins))]
LoginSocketsDep = Annotated[LoginSockets, Depends(_part(lambda s: s.login_sockets))]
LocalizationStudiesDep = Annotated[LocalizationStudies, Depends(_part(lambda s: s.studies))]
StudyTokensDep = Annotated[StudyTokens, Depends(_part(lambda s: s.study_tokens))]
SignupsDep = Annotated[SignupLimits, Depends(_part(lambda s: s.signups))]
TemplatesDep = Annotated[Jinja2Templates, Depends(get_templates)]
CurrentLogin = Annotated[Login | None, Depends(current_login)]
ExperimenterId = Annotated[int, Depends(experimenter_id)]

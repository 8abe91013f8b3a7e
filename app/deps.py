"""Typed request dependencies: what a route may ask of the server, as `Annotated` parameters.

A route names what it needs (`db: DbSession`, `mazes: MazesDep`, `_: ExperimenterId`) instead of
reading `request.app.state`; tests override a dependency with `app.dependency_overrides`.
Works for HTTP routes and websockets alike (both are an `HTTPConnection`). Helpers called outside
a route's parameters (a template's context, a middleware's check) use `get_services`.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Annotated

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


class LoginRequired(Exception):
    """Raised by `experimenter_id` for anonymous requests; create_app answers with a redirect home."""


def get_services(conn: HTTPConnection) -> Services:
    services: Services = conn.app.state.services
    return services


ServicesDep = Annotated[Services, Depends(get_services)]


def get_settings(services: ServicesDep) -> Settings:
    return services.settings


def get_db(services: ServicesDep) -> Iterator[Session]:
    """A session for this request, closed after it; write inside `with db.begin():`."""
    with services.db() as db:
        yield db


def get_db_factory(services: ServicesDep) -> sessionmaker[Session]:
    """Sessions to open as needed: for a socket, which must not hold one for its whole life."""
    return services.db


def get_log(services: ServicesDep) -> EventLog:
    return services.log


def get_hub(services: ServicesDep) -> TrialHub:
    return services.hub


def get_mazes(services: ServicesDep) -> Mazes:
    return services.mazes


def get_seat_tokens(services: ServicesDep) -> SeatTokens:
    return services.seats


def get_robots(services: ServicesDep) -> RobotLinks:
    return services.robots


def get_agents(services: ServicesDep) -> AgentParts:
    return services.agents


def get_clock(services: ServicesDep) -> ServerClock:
    return services.clock


def get_study_files(settings: SettingsDep) -> StudyFiles:
    return StudyFiles.of(settings.data_dir)


def get_webhooks(services: ServicesDep) -> StudyWebhooks:
    return services.webhooks


def get_annotations(services: ServicesDep) -> AnnotationLog:
    return services.annotations


def get_annotator_sessions(services: ServicesDep) -> Sessions:
    return services.annotator_sessions


def get_sessions(services: ServicesDep) -> Sessions:
    return services.sessions


def get_csrf(services: ServicesDep) -> CsrfTokens:
    return services.csrf


def get_logins(services: ServicesDep) -> LoginGuard:
    return services.logins


def get_login_sockets(services: ServicesDep) -> LoginSockets:
    return services.login_sockets


def get_signups(services: ServicesDep) -> SignupLimits:
    return services.signups


def get_localization_studies(services: ServicesDep) -> LocalizationStudies:
    return services.studies


def get_study_tokens(services: ServicesDep) -> StudyTokens:
    return services.study_tokens


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


SettingsDep = Annotated[Settings, Depends(get_settings)]
DbSession = Annotated[Session, Depends(get_db)]
DbFactory = Annotated[sessionmaker[Session], Depends(get_db_factory)]
LogDep = Annotated[EventLog, Depends(get_log)]
HubDep = Annotated[TrialHub, Depends(get_hub)]
MazesDep = Annotated[Mazes, Depends(get_mazes)]
SeatTokensDep = Annotated[SeatTokens, Depends(get_seat_tokens)]
RobotLinksDep = Annotated[RobotLinks, Depends(get_robots)]
AgentsDep = Annotated[AgentParts, Depends(get_agents)]
ClockDep = Annotated[ServerClock, Depends(get_clock)]
SessionsDep = Annotated[Sessions, Depends(get_sessions)]
AnnotationsDep = Annotated[AnnotationLog, Depends(get_annotations)]
StudyFilesDep = Annotated[StudyFiles, Depends(get_study_files)]
WebhooksDep = Annotated[StudyWebhooks, Depends(get_webhooks)]
AnnotatorSessionsDep = Annotated[Sessions, Depends(get_annotator_sessions)]
CsrfDep = Annotated[CsrfTokens, Depends(get_csrf)]
LoginsDep = Annotated[LoginGuard, Depends(get_logins)]
LoginSocketsDep = Annotated[LoginSockets, Depends(get_login_sockets)]
LocalizationStudiesDep = Annotated[LocalizationStudies, Depends(get_localization_studies)]
StudyTokensDep = Annotated[StudyTokens, Depends(get_study_tokens)]
SignupsDep = Annotated[SignupLimits, Depends(get_signups)]
TemplatesDep = Annotated[Jinja2Templates, Depends(get_templates)]
CurrentLogin = Annotated[Login | None, Depends(current_login)]
ExperimenterId = Annotated[int, Depends(experimenter_id)]

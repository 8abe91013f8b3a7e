"""Typed request dependencies: what a route may ask of the server, as `Annotated` parameters.

A route names what it needs (`db: DbSession`, `mazes: MazesDep`, `_: ExperimenterId`) instead of
reading `request.app.state`; tests override a dependency with `app.dependency_overrides`.
Works for HTTP routes and websockets alike (both are an `HTTPConnection`).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Annotated

from fastapi import Depends
from fastapi.templating import Jinja2Templates
from sqlalchemy.orm import Session
from starlette.requests import HTTPConnection

from app.guard import current_login
from app.mazes import Mazes
from app.security import SeatTokens
from app.services import Services
from app.settings import Settings
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


def get_log(services: ServicesDep) -> EventLog:
    return services.log


def get_hub(services: ServicesDep) -> TrialHub:
    return services.hub


def get_mazes(services: ServicesDep) -> Mazes:
    return services.mazes


def get_seat_tokens(services: ServicesDep) -> SeatTokens:
    return services.seats


def get_templates(conn: HTTPConnection) -> Jinja2Templates:
    templates: Jinja2Templates = conn.app.state.templates
    return templates


def experimenter_id(conn: HTTPConnection) -> int:
    """The logged-in experimenter's id; anonymous requests are sent to the login page."""
    login = current_login(conn)
    if login is None:
        raise LoginRequired()
    return login.experimenter_id


SettingsDep = Annotated[Settings, Depends(get_settings)]
DbSession = Annotated[Session, Depends(get_db)]
LogDep = Annotated[EventLog, Depends(get_log)]
HubDep = Annotated[TrialHub, Depends(get_hub)]
MazesDep = Annotated[Mazes, Depends(get_mazes)]
SeatTokensDep = Annotated[SeatTokens, Depends(get_seat_tokens)]
TemplatesDep = Annotated[Jinja2Templates, Depends(get_templates)]
ExperimenterId = Annotated[int, Depends(experimenter_id)]

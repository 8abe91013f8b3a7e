"""`Services`: what one server instance shares between requests (no module-level state)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from sqlalchemy import Engine
from sqlalchemy.orm import Session, sessionmaker

from app.backends.render import FrameRenderer, InThread
from app.clock import ServerClock
from app.login import LoginGuard
from app.login_sockets import LoginSockets
from app.mazes import Mazes
from app.perception.belief import FilterWorker
from app.security import CsrfTokens, SeatTokens, Sessions
from app.settings import Settings
from app.trial.log import EventLog

if TYPE_CHECKING:
    from app.trial.hub import TrialHub
    from app.trial.ldh_belief import BeliefModel
    from app.trial.relay import RedisRelay


@dataclass
class Services:
    settings: Settings
    engine: Engine
    db: sessionmaker[Session]
    clock: ServerClock
    log: EventLog
    seats: SeatTokens
    sessions: Sessions
    csrf: CsrfTokens
    logins: LoginGuard
    mazes: Mazes
    hub: TrialHub = None  # type: ignore[assignment]
    relay: RedisRelay | None = None  # set when ROBOTSLANG_REDIS_URL is: trials shared between processes
    robots: Any = None  # `RobotLinks`: the rovers and cameras connected here (made by `robot_links`)
    ldh_belief: BeliefModel | None = None  # the watch page's LDH belief (made by `belief_model`)
    filters: FilterWorker = field(default_factory=FilterWorker)  # every trial's particle filter turns
    renderer: FrameRenderer = field(default_factory=InThread)  # where simulator frames are drawn
    driver_checks: dict[Any, str | None] = field(default_factory=dict)  # agents' start checks, by file version
    login_sockets: LoginSockets = field(default_factory=LoginSockets)  # experimenters' watch sockets, by login

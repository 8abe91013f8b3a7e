"""`Services`: what one server instance shares between requests (no module-level state).

Built whole by `app.main.build_services`; each part gets only what it uses of the rest (the
hub its `TrialParts`, the backends their `BackendParts`, agent Drivers their `AgentParts`),
and routes ask for a part by a typed dependency (`app.deps`), never for the whole.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from sqlalchemy import Engine
from sqlalchemy.orm import Session, sessionmaker

from app.annotation.log import AnnotationLog
from app.clock import ServerClock
from app.localization_study import LocalizationStudies
from app.login import LoginGuard
from app.login_sockets import LoginSockets
from app.mazes import Mazes
from app.rover.links import RobotLinks
from app.seats.registry import AgentParts
from app.security import CsrfTokens, SeatTokens, Sessions, StudyTokens
from app.settings import Settings
from app.study.signups import SignupLimits
from app.study.webhook import StudyWebhooks
from app.trial.hub import TrialHub
from app.trial.log import EventLog
from app.trial.runtime import TrialParts


@dataclass
class Services:
    settings: Settings
    engine: Engine
    db: sessionmaker[Session]
    clock: ServerClock
    log: EventLog
    seats: SeatTokens
    sessions: Sessions  # experimenters' logins
    annotations: AnnotationLog  # annotators' log, beside the trials'
    annotator_sessions: Sessions  # annotators' logins: their own cookie and salt
    csrf: CsrfTokens
    logins: LoginGuard
    mazes: Mazes
    robots: RobotLinks  # the rovers and cameras connected here
    trials: TrialParts  # what the live trials share (the filters, the renderer, the LDH belief, ...)
    hub: TrialHub  # the live trials of this process (and, with Redis, its relay to the others)
    studies: LocalizationStudies  # LDH human studies
    study_tokens: StudyTokens  # their participants' links
    signups: SignupLimits  # participant studies' consents and lobby joins, per address and per study
    webhooks: StudyWebhooks  # participant studies' webhooks
    login_sockets: LoginSockets = field(default_factory=LoginSockets)  # experimenters' watch sockets, by login

    @property
    def agents(self) -> AgentParts:
        return self.trials.agents

    async def close(self) -> None:
        """Let every trial, process and file go: the server's shutdown, and a self-play worker's."""
        await self.hub.close()
        self.log.close()
        self.webhooks.close()
        self.trials.backends.renderer.close()
        self.mazes.close()
        self.engine.dispose()

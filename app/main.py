"""`create_app(settings)`: the server, with its database upgraded and its services built."""

from __future__ import annotations

import logging
import secrets
import sys
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from datetime import UTC, datetime

from fastapi import FastAPI, Request
from fastapi.exception_handlers import http_exception_handler, request_validation_exception_handler
from fastapi.exceptions import RequestValidationError
from fastapi.responses import FileResponse, RedirectResponse, Response
from fastapi.staticfiles import StaticFiles
from fastapi.templating import Jinja2Templates
from limits.storage import Storage
from sqlalchemy import select
from starlette.exceptions import HTTPException as StarletteHTTPException

from app import i18n
from app.annotation.log import AnnotationLog
from app.backends.registry import BackendParts
from app.backends.render import FrameRenderer, InThread, RenderProcesses
from app.client_limits import shared_counts
from app.clock import ServerClock
from app.db.engine import WalCheckpointer, make_engine, make_sessionmaker, upgrade
from app.db.models import Experimenter
from app.deps import LoginRequired
from app.guard import GuardMiddleware, template_context
from app.i18n import language_of, said
from app.localization_study import LocalizationStudies
from app.login import LoginGuard
from app.mazes import Mazes
from app.perception.belief import FilterWorker
from app.resources import shipped
from app.routes import annotate, experimenter, localization_study, pages, replay, robot_ws, seat_ws, study
from app.rover.links import RobotLinks
from app.seats.registry import AgentParts
from app.security import AccountRole, CsrfTokens, SeatTokens, Sessions, StudyTokens, set_password
from app.services import Services
from app.serving import settle_collector
from app.settings import Settings
from app.study.config import StudyFiles
from app.study.purge import purge_due
from app.study.signups import SignupLimits
from app.study.webhook import StudyWebhooks
from app.trial.frames_store import FrameStore
from app.trial.hub import TrialHub
from app.trial.ldh_belief import BeliefModel
from app.trial.log import EventLog
from app.trial.relay import key_prefix
from app.trial.runtime import TrialParts
from app.trial.watch import WatchParts
from app.web import error_page, wants_html

logger = logging.getLogger("robotslang")


def build_services(settings: Settings) -> Services:
    engine = make_engine(settings)
    upgrade(settings, engine)
    db = make_sessionmaker(engine)
    key = settings.signing_key()

    def counts(what: str) -> Storage | None:  # shared by the processes on one Redis
        return shared_counts(settings.redis_url, key_prefix(settings), what) if settings.redis_url else None

    logins = LoginGuard(
        db,
        settings.login_limit_per_account,
        settings.login_limit_per_address,
        settings.password_check_concurrency,
        storage=counts("logins"),
    )
    clock, mazes, log = ServerClock(), Mazes(settings), EventLog(db)
    seats = SeatTokens(key, settings.join_link_ttl_s)
    robots = RobotLinks(db)
    renderer: FrameRenderer = (
        RenderProcesses(settings.render_processes, settings.benchmark, settings.cache_dir)
        if settings.render_processes
        else InThread()
    )
    webhooks = StudyWebhooks(settings.data_dir, db)
    trials = TrialParts(
        settings=settings,
        db=db,
        log=log,
        clock=clock,
        mazes=mazes,
        frames=FrameStore(settings.frames_dir, db, log),
        backends=BackendParts(mazes, clock, renderer, db, robots, settings.overhead_calibration),
        agents=AgentParts(settings, mazes, clock),
        watch=WatchParts(settings, mazes, FilterWorker(), BeliefModel(settings.ldh_checkpoint, settings.cache_dir)),
        over=webhooks.trial_over,
    )
    return Services(
        settings=settings,
        engine=engine,
        db=db,
        clock=clock,
        log=log,
        seats=seats,
        sessions=Sessions(key, db),
        annotator_sessions=Sessions(key, db, role=AccountRole.ANNOTATOR),
        annotations=AnnotationLog(db),
        csrf=CsrfTokens(key),
        logins=logins,
        mazes=mazes,
        robots=robots,
        trials=trials,
        hub=TrialHub(trials, settings.redis_url),
        studies=LocalizationStudies(settings, db, clock),
        study_tokens=StudyTokens(key),
        signups=SignupLimits(settings, counts("signups")),
        webhooks=webhooks,
    )


def ensure_experimenter(services: Services) -> str | None:
    """With no experimenter yet, create `admin` with a generated password and return it (shown once)."""
    with services.db.begin() as db:
        if db.scalar(select(Experimenter.id).limit(1)) is not None:
            return None
        password = secrets.token_urlsafe(12)
        admin = Experimenter(name="admin")
        set_password(admin, password)
        db.add(admin)
        return password


def create_app(settings: Settings | None = None) -> FastAPI:
    settings = settings or Settings()
    sys.setswitchinterval(settings.gil_switch_interval_s)
    services = build_services(settings)
    password = ensure_experimenter(services)
    with services.db.begin() as db:  # studies whose personal data are due for deletion
        for name, participants in purge_due(
            db, StudyFiles.of(settings.data_dir), services.clock, datetime.now(UTC)
        ).items():
            logger.info("study %s: personal data of %d participant(s) deleted (purge_after_days)", name, participants)
    if password is not None:
        print(f"First start: experimenter 'admin' created with password {password} (shown only once)", flush=True)

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        renderer = services.trials.backends.renderer
        if isinstance(renderer, RenderProcesses):
            renderer.warm_up()
        services.mazes.warm_up()
        checkpoints = WalCheckpointer(services.engine)
        checkpoints.start()
        settle_collector()  # before the trials reopen: theirs is not the start's to freeze
        await services.hub.start()
        yield
        checkpoints.stop()
        await services.close()

    # No /docs or /redoc: they load scripts from a CDN and run inline code, which the CSP forbids.
    app = FastAPI(title="RobotSlang", lifespan=lifespan, docs_url=None, redoc_url=None)
    app.state.services = services
    app.state.templates = Jinja2Templates(directory=str(shipped("templates")), context_processors=[template_context])
    i18n.install(app.state.templates.env)
    app.add_middleware(GuardMiddleware, settings=settings)
    app.mount("/static", StaticFiles(directory=str(shipped("static"))), name="static")
    for routes in (pages, experimenter, seat_ws, robot_ws, replay, localization_study, annotate, study):
        app.include_router(routes.router)
    app.include_router(study.experimenter_router)

    @app.exception_handler(LoginRequired)
    async def _login_required(request: Request, exc: Exception) -> Response:
        return RedirectResponse("/", status_code=303)

    # A person following a link gets a page that says what to do; scripts keep the JSON error.
    @app.exception_handler(StarletteHTTPException)
    async def _http_error(request: Request, exc: StarletteHTTPException) -> Response:
        if not wants_html(request):  # a participant's page script may show the detail: in their language
            exc.detail = said(exc.detail, language_of(request))
            return await http_exception_handler(request, exc)
        return error_page(request, exc.status_code, exc.detail)

    @app.exception_handler(RequestValidationError)
    async def _bad_request(request: Request, exc: RequestValidationError) -> Response:
        if not wants_html(request):
            return await request_validation_exception_handler(request, exc)
        return error_page(request, 404 if request.method == "GET" else 422, None)

    @app.get("/favicon.ico", include_in_schema=False)
    async def _favicon() -> FileResponse:
        return FileResponse(shipped("static") / "favicon.svg", media_type="image/svg+xml")

    return app

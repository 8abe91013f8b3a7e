"""`create_app(settings)`: the server, with its database upgraded and its services built."""

from __future__ import annotations

import logging
import secrets
from contextlib import asynccontextmanager

from fastapi import FastAPI, Request
from fastapi.responses import RedirectResponse
from fastapi.staticfiles import StaticFiles
from fastapi.templating import Jinja2Templates
from sqlalchemy import select

from app.clock import ServerClock
from app.db.engine import make_engine, make_sessionmaker, upgrade
from app.db.models import Experimenter
from app.mazes import Mazes
from app.resources import shipped
from app.routes import experimenter, pages, replay, robot_ws, seat_ws
from app.security import SeatTokens, Sessions, hash_password
from app.services import Services
from app.settings import Settings
from app.trial.hub import TrialHub
from app.trial.log import EventLog

logger = logging.getLogger("robotslang")


def build_services(settings: Settings) -> Services:
    engine = make_engine(settings)
    upgrade(settings, engine)
    db = make_sessionmaker(engine)
    key = settings.signing_key()
    services = Services(settings=settings, engine=engine, db=db, clock=ServerClock(), log=EventLog(db),
                        seats=SeatTokens(key), sessions=Sessions(key), mazes=Mazes(settings))
    services.hub = TrialHub(services)
    return services


def ensure_experimenter(services: Services) -> str | None:
    """With no experimenter yet, create `admin` with a generated password and return it (shown once)."""
    with services.db.begin() as db:
        if db.scalar(select(Experimenter.id).limit(1)) is not None:
            return None
        password = secrets.token_urlsafe(12)
        db.add(Experimenter(name="admin", password_hash=hash_password(password)))
        return password


def create_app(settings: Settings | None = None) -> FastAPI:
    settings = settings or Settings()
    services = build_services(settings)
    password = ensure_experimenter(services)
    if password is not None:
        print(f"First start: experimenter 'admin' created with password {password} (shown only once)",
              flush=True)

    @asynccontextmanager
    async def lifespan(app: FastAPI):
        if settings.redis_url:
            from app.trial.relay import RedisRelay

            services.relay = RedisRelay(services, settings.redis_url)
            await services.relay.start()
        yield
        if services.relay is not None:
            await services.relay.close()  # hands its trials back first
        await services.hub.close()
        services.engine.dispose()

    app = FastAPI(title="RobotSlang", lifespan=lifespan)
    app.state.services = services
    app.state.templates = Jinja2Templates(directory=str(shipped("templates")))
    app.mount("/static", StaticFiles(directory=str(shipped("static"))), name="static")
    app.include_router(pages.router)
    app.include_router(experimenter.router)
    app.include_router(seat_ws.router)
    app.include_router(robot_ws.router)
    app.include_router(replay.router)

    @app.exception_handler(experimenter.LoginRequired)
    async def _login_required(request: Request, exc: Exception):
        return RedirectResponse("/", status_code=303)

    return app

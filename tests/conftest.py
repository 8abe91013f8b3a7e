"""Shared fixtures: where the benchmark is, a private cache and data directory per test run, the
machine's PostgreSQL, and the platform's server, trial and seats.

The platform's parts are imported inside their fixtures: the rover client's tests run with this
file in a venv of the client's own (`.ci/robot-client-floors`), which has no server to import."""

from __future__ import annotations

import os
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

if TYPE_CHECKING:
    from app.settings import Settings
    from tests.app.live import ServerThread

REPO = Path(__file__).resolve().parent.parent


def benchmark_root() -> Path:
    """The benchmark clone: ROBOTSLANG_BENCHMARK, else ../shared/robotslang beside the checkout."""
    env = os.environ.get("ROBOTSLANG_BENCHMARK")
    return Path(env) if env else REPO.parent / "shared" / "robotslang"


@pytest.fixture(scope="session")
def benchmark_path() -> Path:
    root = benchmark_root()
    if not (root / "NDH-data" / "val_seen.json").exists():
        pytest.skip(f"RobotSlang benchmark not found at {root} (set ROBOTSLANG_BENCHMARK to a clone)")
    return root


@pytest.fixture(scope="session", autouse=True)
def _private_cache(tmp_path_factory) -> None:
    # Tests never write into the user's ~/.cache; one cache per run keeps them independent.
    if "ROBOTSLANG_CACHE_DIR" not in os.environ:
        os.environ["ROBOTSLANG_CACHE_DIR"] = str(tmp_path_factory.mktemp("cache"))


def pytest_configure(config) -> None:
    # Options of the platform's fixtures (tests/app/conftest.py), set per test.
    config.addinivalue_line("markers", "settings(**overrides): the `settings` (and so `server`) fixture's overrides")
    config.addinivalue_line("markers", "trial(**options): `make_trial`'s options for the `trial` fixture")


def pytest_collection_modifyitems(items) -> None:
    # Every test that reads the benchmark is marked, so `-m "not benchmark_data"` leaves them out;
    # likewise every test on PostgreSQL (its fixture, or the postgres run of `any_db_settings`).
    for item in items:
        fixtures = getattr(item, "fixturenames", ())
        if "benchmark_path" in fixtures:
            item.add_marker(pytest.mark.benchmark_data)
        callspec = getattr(item, "callspec", None)
        on_postgres = callspec is not None and callspec.params.get("any_db_settings") == "postgres"
        if "postgres_url" in fixtures or on_postgres:
            item.add_marker(pytest.mark.postgres)


REDIS_URL = "redis://127.0.0.1:6379/0"


@pytest.fixture
def redis_url():
    import redis

    try:
        redis.Redis.from_url(REDIS_URL, socket_connect_timeout=2).ping()
    except redis.RedisError as err:
        pytest.skip(f"Redis at {REDIS_URL} not reachable: {err}")
    return REDIS_URL


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


# The machine's PostgreSQL, for the platform's and the deployment's tests.
PG_ADMIN_URL = "postgresql+psycopg://postgres@127.0.0.1:5432/test"


def postgres_reachable() -> str | None:
    """None when the machine's PostgreSQL answers, else why not."""
    from sqlalchemy import create_engine, text

    try:
        engine = create_engine(PG_ADMIN_URL, connect_args={"connect_timeout": 3})
        with engine.connect() as conn:
            conn.execute(text("select 1"))
        engine.dispose()
        return None
    except Exception as err:  # any failure to connect means: skip, saying why
        return f"PostgreSQL at 127.0.0.1:5432/test not reachable: {type(err).__name__}: {str(err)[:120]}"


@pytest.fixture
def postgres_url():
    """A private schema in the `test` database, dropped afterwards."""
    from sqlalchemy import create_engine, text

    why = postgres_reachable()
    if why:
        pytest.skip(why)
    schema = f"rs_{uuid.uuid4().hex[:12]}"
    admin = create_engine(PG_ADMIN_URL)
    with admin.begin() as conn:
        conn.execute(text(f"create schema {schema}"))
    yield f"{PG_ADMIN_URL}?options=-csearch_path%3D{schema}"
    with admin.begin() as conn:
        conn.execute(text(f"drop schema {schema} cascade"))
    admin.dispose()


# The platform's fixtures: a server, a trial on it, its seats (the app's and the browser tests).
@pytest.fixture
def settings(request, tmp_path) -> Settings:
    """The platform's test settings; `@pytest.mark.settings(**overrides)` changes some for one test."""
    from tests.app.live import platform_settings

    marker = request.node.get_closest_marker("settings")
    return platform_settings(tmp_path, **(marker.kwargs if marker else {}))


@pytest.fixture
def server(settings) -> Iterator[ServerThread]:
    """The platform on `settings`, served on a loopback port for the test."""
    from tests.app.live import ServerThread

    with ServerThread(settings) as running:
        yield running


@pytest.fixture
def trial(request, server) -> int:
    """A team's trial on the server's first maze; `@pytest.mark.trial(**make_trial_options)` sets
    its targets, Driver or backend."""
    from bench.live import make_trial

    marker = request.node.get_closest_marker("trial")
    return make_trial(server.services, server.services.mazes.names()[0], **(marker.kwargs if marker else {}))


@pytest.fixture
def seats(server, trial) -> dict[str, str]:
    """The join tokens of the trial's seats, by role (what the experimenter's join links carry)."""
    from app.security import SEAT_ROLES

    return {role: server.services.seats.issue(trial, role) for role in SEAT_ROLES}

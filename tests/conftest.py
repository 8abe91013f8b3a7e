"""Shared fixtures: where the benchmark is, a private cache and data directory per test run, the
machine's PostgreSQL, and the platform's server, trial and seats.

The platform's parts are imported inside their fixtures: the rover client's tests run with this
file in a venv of the client's own (`.ci/robot-client-floors`), which has no server to import."""

from __future__ import annotations

import os
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

if TYPE_CHECKING:
    from app.settings import Settings
    from tests.app.live import PlatformProcess, ServerThread, TrialHandle, Trials

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
    # Options of the platform's fixtures (below), set per test.
    config.addinivalue_line(
        "markers",
        "settings(**overrides): overrides of the `settings` fixture (and so of `server`, `start_server`, `cluster`,"
        " `server_process`)",
    )
    config.addinivalue_line("markers", "trial(**options): `trials.new`'s options for the `trial` fixture")


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


# The platform's fixtures: a server, trials on it and their seats (the app's and the browser tests).
# Only these build servers (`ServerThread`, `PlatformProcess`): a test asks for one, and it is
# stopped when the test ends.
def _settings_overrides(request) -> dict:
    marker = request.node.get_closest_marker("settings")
    return dict(marker.kwargs) if marker else {}


class StartServer:
    """`start_server(settings=None, **overrides)`: a started server, stopped when the fixture's
    scope ends (or earlier, by its `stop()`). Without `settings`, the fixture's own settings with
    `overrides` changed."""

    def __init__(self, node, default: Callable[..., Settings]) -> None:
        self._node = node  # the test (or module) whose end stops the servers
        self._default = default

    def __call__(self, settings: Settings | None = None, **overrides) -> ServerThread:
        from tests.app.live import ServerThread

        if settings is None:
            settings = self._default(**overrides)
        elif overrides:
            raise TypeError("start_server takes settings or overrides of the default settings, not both")
        server = ServerThread(settings)
        # Registered now, not at the fixture's teardown: a server started on a database fixture
        # set up after `start_server` (a PostgreSQL schema) still stops before that is dropped.
        self._node.addfinalizer(server.stop)
        return server.start()


@pytest.fixture
def settings(request, tmp_path) -> Settings:
    """The platform's test settings; `@pytest.mark.settings(**overrides)` changes some for one test."""
    from tests.app.live import platform_settings

    return platform_settings(tmp_path, **_settings_overrides(request))


@pytest.fixture
def start_server(request, settings, tmp_path) -> StartServer:
    """Servers the test starts itself: after writing what the server must find (a database,
    mazes, a study), on settings of its own, or again on the same data to see what survived."""
    from tests.app.live import platform_settings

    def default(**overrides) -> Settings:
        if not overrides:
            return settings
        return platform_settings(tmp_path, **{**_settings_overrides(request), **overrides})

    return StartServer(request.node, default)


@pytest.fixture(scope="module")
def start_module_server(request, tmp_path_factory) -> StartServer:
    """`start_server` for a module's fixtures: its servers serve every test of the module. Without
    `settings`, each is on a data directory of its own."""
    from tests.app.live import platform_settings

    def default(**overrides) -> Settings:
        return platform_settings(tmp_path_factory.mktemp("server"), **overrides)

    return StartServer(request.node, default)


@pytest.fixture
def server(settings, start_server) -> ServerThread:
    """The platform on `settings`, served on a loopback port for the test."""
    return start_server(settings)


@pytest.fixture
def cluster(request, tmp_path, postgres_url, redis_url, start_server) -> tuple[ServerThread, ServerThread]:
    """Two servers on one PostgreSQL database and one Redis, as two processes of a deployment
    share them (`@pytest.mark.settings` applies to both); the second started after the first."""
    from tests.app.live import platform_settings

    shared = platform_settings(tmp_path, database_url=postgres_url, redis_url=redis_url, **_settings_overrides(request))
    return start_server(shared), start_server(shared)


@pytest.fixture
def server_process(request, settings) -> Callable[..., PlatformProcess]:
    """`server_process(own_settings=None, workers=1)`: `robotslang serve` as a process on
    `own_settings`, else the `settings` fixture's, with the platform's services beside it; built
    unstarted, so a test sets up its data before `start()`; stopped when the test ends."""
    from tests.app.live import PlatformProcess

    def build(own_settings: Settings | None = None, workers: int = 1) -> PlatformProcess:
        server = PlatformProcess(own_settings or settings, workers=workers)
        request.node.addfinalizer(server.close)
        return server

    return build


@pytest.fixture
def trials(request) -> Trials:
    """`trials.new(on=None, maze=None, **options)`: a new team's trial, `trials.of(trial_id, on=None)`:
    one the platform made; each a `TrialHandle` (its id, its seats' tokens and links), on the
    server `on`, by default the `server` fixture's."""
    from tests.app.live import Trials

    return Trials(lambda: request.getfixturevalue("server"))


@pytest.fixture
def trial(request, trials) -> TrialHandle:
    """A team's trial on the `server` fixture's first maze; `@pytest.mark.trial(**options)` sets
    its targets, Driver or backend (`trials.new`'s options)."""
    marker = request.node.get_closest_marker("trial")
    return trials.new(**(marker.kwargs if marker else {}))

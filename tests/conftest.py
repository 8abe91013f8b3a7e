"""Shared fixtures: where the benchmark is, and a private cache and data directory per test run."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

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

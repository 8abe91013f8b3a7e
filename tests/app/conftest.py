"""Fixtures for the platform: settings on a private data directory, on SQLite or PostgreSQL."""

from __future__ import annotations

import uuid

import pytest
from sqlalchemy import create_engine, text

from app.settings import Settings

PG_ADMIN_URL = "postgresql+psycopg://postgres@127.0.0.1:5432/test"


def postgres_reachable() -> str | None:
    """None when the machine's PostgreSQL answers, else why not."""
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


def platform_settings(tmp_path, database_url: str | None = None, **overrides) -> Settings:
    values = dict(
        data_dir=tmp_path / "var",
        database_url=database_url,
        secret_key="test-secret",
        min_move_interval_s=0.0,
        grace_period_s=30.0,
        render_processes=0,  # frames drawn in a thread; tests/app/test_render_processes.py runs the pool
    )
    values.update(overrides)
    return Settings(**values)


@pytest.fixture(params=["sqlite", "postgres"])
def any_db_settings(request, tmp_path):
    """Settings on a real SQLite file, then again on the machine's PostgreSQL."""
    if request.param == "sqlite":
        return platform_settings(tmp_path)
    return platform_settings(tmp_path, database_url=request.getfixturevalue("postgres_url"))


@pytest.fixture
def settings(tmp_path) -> Settings:
    return platform_settings(tmp_path)

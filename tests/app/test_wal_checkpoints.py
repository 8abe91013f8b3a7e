"""SQLite's WAL is copied back by the server's checkpoint thread, never by a commit on the loop."""

from __future__ import annotations

import time

import pytest
from sqlalchemy import text

from app.db.engine import WalCheckpointer, make_engine, upgrade
from app.settings import Settings

PAST_AUTOCHECKPOINT = 6000  # rows of 1 kB: past the 1,000 pages at which a commit checkpoints


@pytest.fixture
def database(tmp_path):
    settings = Settings(data_dir=tmp_path)
    engine = make_engine(settings)
    upgrade(settings, engine)
    yield engine, tmp_path / "robotslang.db"
    engine.dispose()


def write_pages(engine, rows: int) -> None:
    with engine.begin() as conn:
        conn.execute(text("CREATE TABLE IF NOT EXISTS filler (id INTEGER PRIMARY KEY, body TEXT)"))
        conn.execute(text("INSERT INTO filler (body) VALUES (:body)"), [{"body": "x" * 1000}] * rows)


def autocheckpoint(engine) -> int:
    with engine.connect() as conn:
        return conn.exec_driver_sql("PRAGMA wal_autocheckpoint").scalar()


def test_commits_leave_the_wal_to_the_checkpointer_until_it_stops(database):
    engine, file = database
    checkpoints = WalCheckpointer(engine, interval_s=3600)  # started, but not yet due
    checkpoints.start()
    assert autocheckpoint(engine) == 0
    before = file.stat().st_size
    write_pages(engine, PAST_AUTOCHECKPOINT)
    assert file.stat().st_size == before  # all of it still in the WAL: the commit did not copy it
    checkpoints.stop()  # at the server's shutdown: what is left is copied back
    assert file.stat().st_size > before + 5_000_000
    assert autocheckpoint(engine) == 1000  # commits checkpoint again, as in any other process


def test_the_checkpointer_copies_the_wal_back_every_interval(database):
    engine, file = database
    checkpoints = WalCheckpointer(engine, interval_s=0.2)
    checkpoints.start()
    try:
        before = file.stat().st_size
        write_pages(engine, PAST_AUTOCHECKPOINT)
        deadline = time.monotonic() + 10
        while file.stat().st_size < before + 5_000_000 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert file.stat().st_size > before + 5_000_000
    finally:
        checkpoints.stop()


def test_without_it_a_commit_checkpoints_as_sqlite_does(database):
    engine, file = database
    before = file.stat().st_size
    write_pages(engine, PAST_AUTOCHECKPOINT)
    assert file.stat().st_size > before + 5_000_000

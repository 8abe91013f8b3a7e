"""Engine and sessions from `Settings`; the schema is brought up to date with Alembic."""

from __future__ import annotations

import logging
import sqlite3
import threading
import time
import weakref

from alembic import command
from alembic.config import Config
from sqlalchemy import Engine, create_engine, event
from sqlalchemy.orm import Session, sessionmaker

from app.resources import shipped
from app.settings import Settings


def make_engine(settings: Settings) -> Engine:
    url = settings.url
    if url.startswith("sqlite"):
        settings.data_dir.mkdir(parents=True, exist_ok=True)
        engine = create_engine(url, connect_args={"check_same_thread": False, "timeout": 30})

        @event.listens_for(engine, "connect")
        def _sqlite_pragmas(dbapi_connection: sqlite3.Connection, _record: object) -> None:
            # WAL: readers never block the writer; NORMAL is durable across a process kill.
            cursor = dbapi_connection.cursor()
            cursor.execute("PRAGMA journal_mode=WAL")
            cursor.execute("PRAGMA synchronous=NORMAL")
            cursor.execute("PRAGMA foreign_keys=ON")
            # What is erased (a withdrawal's name and free text) is overwritten with zeros, not left
            # in free space or freed pages (Debian builds SQLite so; others do not); its older
            # copies in the WAL go with `truncate_wal`.
            cursor.execute("PRAGMA secure_delete=ON")
            if engine in _CHECKPOINTED:  # a `WalCheckpointer` copies the WAL back, not the commits
                cursor.execute("PRAGMA wal_autocheckpoint=0")
            cursor.close()

        return engine
    return create_engine(url, pool_pre_ping=True)


logger = logging.getLogger(__name__)
_CHECKPOINTED: weakref.WeakSet[Engine] = weakref.WeakSet()


class WalCheckpointer:
    """On SQLite, the WAL copied back into the database by a thread of its own. By default the
    commit that takes the WAL past 1,000 pages does it, with an fsync: in the server that commit
    runs on the event loop (`EventLog`), and with 200 live trials one in a few hundred stopped
    every trial for up to 55 ms. The thread checkpoints once every `interval_s` (PASSIVE: it never
    waits on a reader or a writer; sqlite releases the GIL meanwhile). Nothing to do elsewhere."""

    def __init__(self, engine: Engine, interval_s: float = 1.0) -> None:
        self.engine, self.interval_s = engine, interval_s
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        if self.engine.dialect.name != "sqlite" or self._thread is not None:
            return
        _CHECKPOINTED.add(self.engine)
        self.engine.dispose()  # connections made before this still checkpoint at their commits
        self._thread = threading.Thread(target=self._run, name="wal-checkpoints", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        if self._thread is None:
            return
        self._stop.set()
        self._thread.join()
        self._thread = None
        self._checkpoint()  # what the last second wrote
        _CHECKPOINTED.discard(self.engine)
        self.engine.dispose()  # its connections checkpoint at their commits again

    def _run(self) -> None:
        while not self._stop.wait(self.interval_s):
            self._checkpoint()

    def _checkpoint(self) -> None:
        try:
            with self.engine.connect() as conn:
                conn.exec_driver_sql("PRAGMA wal_checkpoint(PASSIVE)")
        except Exception:  # the next one catches up; a commit never depends on it
            logger.exception("WAL checkpoint failed")


def truncate_wal(engine: Engine, attempts: int = 10) -> bool:
    """On SQLite, copy the whole WAL back and cut its file to nothing: rows just erased leave no
    older copy in a frame of it (a PASSIVE checkpoint copies frames back but keeps the file, and a
    reset WAL overwrites it only as it is written again). It waits for readers and writers, up to
    the busy timeout per attempt; False (logged) if they never let it finish. Elsewhere nothing to
    do here (docs/study.md: PostgreSQL's VACUUM)."""
    if engine.dialect.name != "sqlite":
        return True
    for _ in range(attempts):
        with engine.connect() as conn:
            busy, _, _ = conn.exec_driver_sql("PRAGMA wal_checkpoint(TRUNCATE)").one()
        if not busy:
            return True
        time.sleep(0.1)
    logger.warning("the WAL could not be truncated: erased rows may keep a copy in it until the next checkpoint")
    return False


def make_sessionmaker(engine: Engine) -> sessionmaker[Session]:
    return sessionmaker(engine, expire_on_commit=False)


def alembic_config(settings: Settings) -> Config:
    config = Config()
    config.set_main_option("script_location", str(shipped("migrations")))
    config.set_main_option("sqlalchemy.url", settings.url.replace("%", "%%"))
    return config


def upgrade(settings: Settings, engine: Engine | None = None) -> None:
    """Bring the database to the latest revision (creates it when new)."""
    config = alembic_config(settings)
    engine = engine or make_engine(settings)
    with engine.begin() as connection:
        config.attributes["connection"] = connection
        command.upgrade(config, "head")


def open_database(settings: Settings) -> sessionmaker[Session]:
    """Sessions on the settings' database, brought up to date first (for commands run outside the server)."""
    engine = make_engine(settings)
    upgrade(settings, engine)
    return make_sessionmaker(engine)

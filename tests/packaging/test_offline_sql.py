"""`alembic upgrade head --sql` prints the schema for the configured database without reaching it."""

from __future__ import annotations

import subprocess
import sys

from tests.packaging.outside import REPO, clean_env


def offline_sql(tmp_path, **env: str) -> str:
    out = subprocess.run(
        [sys.executable, "-m", "alembic", "upgrade", "head", "--sql"],
        cwd=REPO,
        env=clean_env(PYTHONPATH=str(REPO), ROBOTSLANG_DATA_DIR=str(tmp_path / "var"), **env),
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr
    return out.stdout


def test_sqlite_ddl_without_creating_the_database(tmp_path):
    sql = offline_sql(tmp_path)
    assert "CREATE TABLE event" in sql and "INSERT INTO alembic_version (version_num) VALUES ('0001')" in sql
    assert not (tmp_path / "var").exists()


def test_postgresql_ddl_for_a_server_that_is_not_there(tmp_path):
    # A port nothing listens on: offline mode must not try to connect.
    sql = offline_sql(tmp_path, ROBOTSLANG_DATABASE_URL="postgresql+psycopg://nobody@127.0.0.1:9/none")
    assert "CREATE TABLE event" in sql and "SERIAL" in sql.upper()

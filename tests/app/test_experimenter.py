"""The experimenter's side: first start, accounts from the command line, login, participants,
teams and trials with join links, maze choice, and the database commands."""

from __future__ import annotations

import html
import re

import httpx
import pytest
from sqlalchemy import create_engine, inspect, select

from app.db.models import Trial
from app.main import build_services, ensure_experimenter
from tests.app.live import browser, cli, experimenter_client, open_seats, submit_login


def test_first_start_creates_admin_once(settings):
    services = build_services(settings)
    password = ensure_experimenter(services)
    assert password and len(password) >= 12
    assert ensure_experimenter(services) is None, "the password is generated and shown only once"
    services.engine.dispose()


@pytest.mark.slow
def test_admin_create_and_db_upgrade_commands(tmp_path, start_server):
    env = {"ROBOTSLANG_DATA_DIR": str(tmp_path / "var"), "ROBOTSLANG_SECRET_KEY": "k"}
    done = cli("db", "upgrade", env=env)
    assert done.returncode == 0, done.stderr
    tables = set(inspect(create_engine(f"sqlite:///{tmp_path / 'var' / 'robotslang.db'}")).get_table_names())
    assert {"experimenter", "participant", "team", "robot", "trial", "event", "frame"} <= tables
    done = cli("admin", "create", "alice", "--password", "s3cret-enough", env=env)
    assert done.returncode == 0 and "created" in done.stdout, done.stderr
    done = cli("admin", "create", "bob", env=env, input="another-pass\nanother-pass\n")
    assert done.returncode == 0 and "created" in done.stdout, done.stderr + done.stdout
    done = cli("admin", "create", "carol", "--password", "short", env=env)
    assert done.returncode != 0 and "--password" in done.stderr and "8 characters" in done.stderr

    from app.settings import Settings

    server = start_server(Settings(data_dir=tmp_path / "var", secret_key="k"))  # as the commands set it
    client = browser(server.url)
    bad = submit_login(client, "alice", "wrong")
    assert bad.status_code == 401 and "wrong password" in bad.text
    assert "Participants" in submit_login(client, "bob", "another-pass").text


def test_experimenter_forms_make_a_trial_with_join_links(server):
    assert httpx.get(server.url + "/experimenter").status_code == 303, "the dashboard is behind login"
    client = experimenter_client(server.services, server.url)
    for name in ("Ada", "Ben", "Cy"):
        client.post("/experimenter/participants", data={"name": name})
    page = client.post("/experimenter/participants", data={"name": "Ada"}).text
    assert "already exists" in page
    page = client.post("/experimenter/teams", data={"name": "Solo", "member_a": 1, "member_b": 1}).text
    assert "two different participants" in page
    client.post("/experimenter/teams", data={"name": "Pair", "member_a": 1, "member_b": 2})
    client.post("/experimenter/teams", data={"name": "Other", "member_a": 2, "member_b": 3})
    page = client.post("/experimenter/trials", data={"team_id": 1, "targets": "mug,jar,paddle"}).text
    links = dict(re.findall(r'class="join-(\w+)" href="([^"]+)"', page))
    assert set(links) == {"commander", "driver"}
    assert "Commander Ada · Driver Ben" in page and ">commander (Ada)</a>" in page and ">driver (Ben)</a>" in page
    assert "Commander" in client.get(links["commander"]).text
    page = client.post("/experimenter/trials", data={"team_id": 1, "targets": "mug,mug,jar"}).text
    assert "give each of jar, mug, paddle once" in page
    names = sorted(server.services.mazes.names())
    with server.services.db() as db:
        first = db.scalar(select(Trial).where(Trial.team_id == 1))
    assert first.maze == names[0] and first.targets == ["mug", "jar", "paddle"]
    # Ben holds a seat in Pair's trial, not yet over: team Other gets no trial until it ends.
    page = html.unescape(client.post("/experimenter/trials", data={"team_id": 2}).text)
    assert f"team 'Other': a member is in trial {first.id}, which is waiting;" in page
    open_seats(server, first.id, "commander", "driver")
    client.post(f"/experimenter/trials/{first.id}/abort")
    # Ben played maze 0 with Pair: team Other may not get its layout, and is given the next unseen one
    # (with the benchmark present, Run_117 is Run_114's layout under another name).
    layouts = server.services.mazes.layouts()
    unseen = [name for name in names if layouts[name] != layouts[names[0]]]
    page = client.post("/experimenter/trials", data={"team_id": 2, "maze": names[0]}).text
    assert "already seen it" in page
    page = html.unescape(client.post("/experimenter/trials", data={"team_id": 2, "backend": "robot:42"}).text)
    assert "no registered rover with id '42'" in page
    page = html.unescape(client.post("/experimenter/trials", data={"team_id": 2, "driver": "agent:nobody"}).text)
    assert "neither 'human' nor a known agent" in page
    client.post("/experimenter/trials", data={"team_id": 2, "driver": "oracle:shortest"})
    with server.services.db() as db:
        second = db.scalar(select(Trial).where(Trial.team_id == 2))
    assert second.maze == unseen[0] and sorted(second.targets) == ["jar", "mug", "paddle"]
    assert second.driver == "oracle:shortest" and second.driver_id is None
    row = re.search(rf'data-trial="{second.id}".*?</tr>', client.get("/experimenter").text, re.S).group(0)
    assert "join-commander" in row and "join-driver" not in row, "an agent drives: no Driver link"
    row = re.search(rf'data-trial="{first.id}".*?</tr>', client.get("/experimenter").text, re.S).group(0)
    assert "join-" not in row and "/replay" in row, "an aborted trial offers its replay, not its join links"


@pytest.mark.parametrize("kind", ["sqlite", "postgres"])
def test_database_upgrade_is_idempotent(tmp_path, kind, request):
    from alembic.autogenerate import compare_metadata
    from alembic.migration import MigrationContext

    from app.db.engine import make_engine, upgrade
    from app.db.models import Base
    from tests.app.live import platform_settings

    url = request.getfixturevalue("postgres_url") if kind == "postgres" else None
    settings = platform_settings(tmp_path, database_url=url)
    engine = make_engine(settings)
    upgrade(settings, engine)
    upgrade(settings, engine)
    with engine.connect() as conn:  # the migrations build exactly the tables the models describe
        assert compare_metadata(MigrationContext.configure(conn), Base.metadata) == []
    engine.dispose()

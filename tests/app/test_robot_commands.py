"""`robotslang robot create|list`: the token is printed once and accepted by the server's check;
the list never shows it; bad names and roles are refused by name."""

from __future__ import annotations

import pytest
from sqlalchemy import create_engine
from sqlalchemy.orm import Session

from app.backends.remote import robot_for_token
from tests.app.test_experimenter import cli


@pytest.mark.slow
def test_robot_create_prints_a_working_token_once_and_list_shows_the_robots(tmp_path):
    env = {"ROBOTSLANG_DATA_DIR": str(tmp_path / "var"), "ROBOTSLANG_SECRET_KEY": "k"}
    made = cli("robot", "create", "rover 1", env=env)
    assert made.returncode == 0, made.stderr
    token = made.stdout.splitlines()[2]
    assert "robot 'rover 1' (driver) registered" in made.stdout and "backend robot:1" in made.stdout
    assert f"robotslang-robot --server URL --token {token}" in made.stdout
    camera = cli("robot", "create", "table camera", "--role", "overhead", env=env)
    assert camera.returncode == 0 and "--role overhead" in camera.stdout, camera.stderr

    with Session(create_engine(f"sqlite:///{tmp_path / 'var' / 'robotslang.db'}")) as db:
        assert robot_for_token(db, token).name == "rover 1"

    listed = cli("robot", "list", env=env)
    assert listed.returncode == 0, listed.stderr
    rows = [line.split(None, 3) for line in listed.stdout.splitlines()]
    assert rows == [["1", "driver", "robot:1", "rover 1"], ["2", "overhead", "-", "table camera"]]
    assert token not in listed.stdout

    again = cli("robot", "create", "rover 1", env=env)
    assert again.returncode != 0 and "robot 'rover 1' already exists" in again.stderr
    bad = cli("robot", "create", "rover 2", "--role", "pilot", env=env)
    assert bad.returncode != 0 and "--role" in bad.stderr and "robot role 'pilot'" in bad.stderr
    assert cli("robot", "list", env=env).stdout == listed.stdout, "a refused robot is not registered"

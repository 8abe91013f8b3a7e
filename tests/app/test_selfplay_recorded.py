"""`robotslang eval selfplay --record DIR`: whole trials with `agent:dialog` in both seats played
through the platform's trial core, recorded as ordinary trials that replay and export."""

from __future__ import annotations

import json

import pytest
from sqlalchemy import select

from app.db.engine import make_engine, make_sessionmaker
from app.db.models import Event, Trial
from app.settings import Settings
from tests.app.live import cli

KEYS = {
    "trials",
    "completed",
    "targets_confirmed_mean",
    "moves_ratio",
    "messages_mean",
    "first_estimate_td_m",
    "false_confirmations",
    "seconds_per_trial",
}


@pytest.mark.slow
def test_selfplay_through_the_trial_core_records_ordinary_trials(tmp_path):
    data = tmp_path / "var"
    env = {"ROBOTSLANG_MIN_MOVE_INTERVAL_S": "0", "ROBOTSLANG_RENDER_PROCESSES": "0"}
    done = cli("eval", "selfplay", "--record", str(data), "--limit", "1", "--json", env=env)
    assert done.returncode == 0, done.stderr[-2000:]
    figures = json.loads(done.stdout.strip().splitlines()[-1])
    assert set(figures) == KEYS
    assert figures["trials"] == 1 and figures["completed"] == 1.0 and figures["targets_confirmed_mean"] == 3
    assert figures["false_confirmations"] == 0 and figures["first_estimate_td_m"] is not None
    assert figures["moves_ratio"] >= 1.0 and figures["messages_mean"] > 0

    settings = Settings(data_dir=data)
    engine = make_engine(settings)
    with make_sessionmaker(engine)() as db:
        (trial,) = db.scalars(select(Trial)).all()
        kinds = set(db.scalars(select(Event.kind).where(Event.trial_id == trial.id)))
    engine.dispose()
    assert (trial.phase, trial.commander, trial.driver, trial.team_id) == (
        "finished",
        "agent:dialog",
        "agent:dialog",
        None,
    )
    assert {"chat", "localization", "move_executed", "frame", "target_confirmed"} <= kinds

    exported = cli(
        "export",
        "all",
        "--format",
        "ndh",
        "--out",
        str(tmp_path / "ndh"),
        env={**env, "ROBOTSLANG_DATA_DIR": str(data)},
    )
    assert exported.returncode == 0, exported.stderr[-2000:]
    assert (tmp_path / "ndh" / "NDH-data").is_dir()

"""`robotslang eval selfplay` on the bundled mazes (no benchmark): whole trials with the project's
agents in both seats, in parallel processes, printing the figures as JSON."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

KEYS = [
    "trials",
    "completed",
    "targets_confirmed_mean",
    "moves_ratio",
    "messages_mean",
    "first_estimate_td_m",
    "false_confirmations",
    "first_mark_within_0_5m",
    "bumps_per_instruction",
    "seconds_per_trial",
]
ROOT = Path(__file__).resolve().parents[2]


def _selfplay(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k != "ROBOTSLANG_BENCHMARK"}
    env["PYTHONPATH"] = str(ROOT)
    return subprocess.run(
        [sys.executable, "-m", "app.cli", "eval", "selfplay", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        env=env,
        timeout=300,
    )


@pytest.mark.slow
def test_selfplay_on_bundled_mazes_completes_every_trial(tmp_path):
    """Every bundled maze, all three targets confirmed: the Commander routes around the landmarks
    that block the robot (it routed through the paddle of gen-000 and gen-001 on the platform)."""
    per_trial = tmp_path / "trials.jsonl"
    result = _selfplay("--processes", "2", "--json", "--per-trial", str(per_trial), cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    figures = json.loads(result.stdout)
    assert list(figures) == KEYS
    rows = [json.loads(line) for line in per_trial.read_text().splitlines()]
    assert [r["maze"] for r in rows] == [f"gen-{k:03d}" for k in range(12)]
    assert [r["maze"] for r in rows if not r["completed"]] == []
    assert figures["trials"] == 12 and figures["completed"] == 1.0 and figures["targets_confirmed_mean"] == 3.0
    assert figures["false_confirmations"] == 0 and figures["first_estimate_td_m"] <= 0.5
    assert all(r["dialog"][0][0] == "commander" for r in rows)


def test_selfplay_with_the_cheating_driver_and_a_bad_benchmark(tmp_path):
    result = _selfplay("--limit", "1", "--processes", "1", "--driver", "oracle", "--json", cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["trials"] == 1
    bad = _selfplay("--benchmark", str(tmp_path), "--json", cwd=tmp_path)
    assert bad.returncode == 2 and "NDH-data" in bad.stderr


def test_selfplay_with_a_persona_driver(tmp_path):
    """`--driver persona:NAME` seats the dialog Driver speaking as a frozen Driver persona; the
    platform has no such seat, so --record refuses it."""
    per_trial = tmp_path / "trials.jsonl"
    args = ("--limit", "1", "--processes", "1", "--driver", "persona:chatty", "--json")
    result = _selfplay(*args, "--per-trial", str(per_trial), cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    figures = json.loads(result.stdout)
    assert figures["trials"] == 1 and 0.0 <= figures["bumps_per_instruction"] <= 1.0
    dialog = json.loads(per_trial.read_text())["dialog"]
    assert not any(text.startswith("ok, ") and text.endswith("what next?") for role, text in dialog if role == "driver")
    refused = _selfplay(*args, "--record", str(tmp_path / "data"), cwd=tmp_path)
    assert refused.returncode == 2 and "'persona:chatty' (it seats: dialog)" in refused.stderr

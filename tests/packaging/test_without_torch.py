"""The server's and the simulator's commands run where torch is not installed; the learned
Driver's commands say which extra they need."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from tests.packaging.outside import REPO, clean_env

# Each test starts the whole CLI in a fresh interpreter.
pytestmark = pytest.mark.slow


def robotslang_without_torch(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", "import tests.packaging.no_torch; from app.cli import main; main()", *args],
        cwd=REPO,
        env=clean_env(PYTHONPATH=str(REPO)),
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_help_and_the_bundled_mazes_need_no_torch():
    assert robotslang_without_torch("--help").returncode == 0
    listed = robotslang_without_torch("mazes", "list")
    assert listed.returncode == 0 and "gen-011" in listed.stdout


def test_baselines_evaluate_without_torch(benchmark_path):
    out = robotslang_without_torch(
        "eval",
        "baselines",
        "--benchmark",
        str(benchmark_path),
        "--split",
        "val_seen",
        "--agent",
        "stop",
        "--start",
        "recorded",
        "--json",
    )
    assert out.returncode == 0, out.stderr
    summary = json.loads(out.stdout)
    assert summary["split"] == "val_seen" and summary["n"] > 0 and set(summary["agents"]) == {"stop"}


def test_a_learned_driver_command_names_the_extra_it_needs(benchmark_path, tmp_path):
    out = robotslang_without_torch(
        "eval",
        "ndh",
        "--benchmark",
        str(benchmark_path),
        "--checkpoint",
        str(tmp_path / "best.pt"),
        "--split",
        "test",
        "--json",
    )
    assert out.returncode == 1
    assert "pip install 'robotslang[learn]'" in out.stderr and "Traceback" not in out.stderr

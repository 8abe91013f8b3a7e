"""`robotslang bench sim` prints every speed figure of the simulator (on a few maps, to stay fast)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROBOTSLANG = Path(sys.executable).parent / "robotslang"


@pytest.mark.slow
def test_bench_sim_prints_every_figure(benchmark_path, tmp_path):
    env = {**os.environ, "COLUMNS": "160"}
    # Run from elsewhere: the installed command finds `bench` as an installed package.
    result = subprocess.run(
        [str(ROBOTSLANG), "bench", "sim", "--benchmark", str(benchmark_path), "--maps", "2"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env=env,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    for figure in (
        "PNG decode, 2 maps",
        "graph + all-pairs, 2 maps",
        "ray table, 2 maps",
        "graphs + all-pairs + rays, 2 maps",
        "env step, unwrapped",
        "env step, gymnasium.make",
        "batch steps/s with observations, batch 100",
        "batch steps/s with observations, batch 1000",
        "first-person render, 320x240",
        "learner iteration, student forcing",
    ):
        assert figure in result.stdout, f"{figure!r} missing from:\n{result.stdout}"


def test_bench_sim_json_has_exactly_the_figures_a_script_holds_against_targets(benchmark_path, tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "bench.sim", "--benchmark", str(benchmark_path), "--maps", "2", "--json"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    figures = json.loads(result.stdout)
    assert set(figures) == {
        "all_maps_s",
        "png_decode_s",
        "env_step_us",
        "batch_steps_per_s_1000",
        "render_fps_320x240",
        "rollout_iter_s",
    }
    assert all(isinstance(v, float) and v > 0 for v in figures.values())
    assert "load average" in result.stderr


def test_bench_sim_names_a_missing_benchmark(tmp_path):
    result = subprocess.run(
        [str(ROBOTSLANG), "bench", "sim", "--benchmark", str(tmp_path / "nowhere")],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=120,
    )
    assert result.returncode != 0
    assert "nowhere" in result.stderr + result.stdout and "NDH-data" in result.stderr + result.stdout

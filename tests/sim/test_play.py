"""`robotslang sim play`: driving by hand from typed or piped moves, frames written per move."""

from __future__ import annotations

import re

import cv2
import pytest
import typer
from typer.testing import CliRunner

from sim import cli as sim_commands
from sim.cli import play
from sim.core.dynamics import Action
from sim.core.labels import Label
from tests.sim.synthetic import synthetic_maze


@pytest.fixture(scope="module")
def cli():
    root = typer.Typer()
    sim_commands.register(root, typer.Typer())
    return root


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    # A blue wall across the table at x ~ 1.4 m (column 795 onward).
    maze = synthetic_maze([(Label.BLUE, 795, 10, 806, 900)])
    folder = tmp_path_factory.mktemp("runs") / "Run_synthetic"
    maze.save(folder)
    return folder


def test_parse_moves():
    assert play.parse_moves("w forward wad") == [
        Action.FORWARD,
        Action.FORWARD,
        Action.FORWARD,
        Action.LEFT,
        Action.RIGHT,
    ]
    assert play.parse_moves("left q") == [Action.LEFT, None]
    with pytest.raises(ValueError, match="'jump'"):
        play.parse_moves("w jump")


def test_driving_writes_both_frames_per_move(cli, run_dir, tmp_path):
    out = tmp_path / "frames"
    result = CliRunner().invoke(
        cli, ["sim", "play", "--maze", str(run_dir), "--out", str(out), "--start", "0.7,1.0,0"], input="ww\nhop\nd\nq\n"
    )
    assert result.exit_code == 0, result.output
    assert "unknown move 'hop'" in result.output
    assert "step 3: x=0.84 y=0.98 heading=315 deg" in result.output
    for step in range(4):
        fp = cv2.imread(str(out / f"step-{step:03d}-first-person.png"))
        td = cv2.imread(str(out / f"step-{step:03d}-top-down.png"))
        assert fp.shape == (480, 640, 3) and td.shape == (588, 700, 3)
    assert not (out / "step-004-first-person.png").exists()
    assert (out / "latest-top-down.png").read_bytes() == (out / "step-003-top-down.png").read_bytes()


def test_driving_into_the_wall_is_a_collision(cli, run_dir, tmp_path):
    result = CliRunner().invoke(
        cli,
        ["sim", "play", "--maze", str(run_dir), "--out", str(tmp_path), "--start", "1.2,1.0,0"],
        input="wwwwwwww\ns\n",
    )
    assert result.exit_code == 0, result.output
    assert "collision: " in result.output and "ahead blue" in result.output
    assert "stopped after 9 moves" in result.output


@pytest.mark.parametrize(
    "args, message",
    [
        (["--maze", "Run_nowhere"], "unknown maze 'Run_nowhere'"),
        (["--maze", "Run_nowhere", "--benchmark", "/nonexistent"], "/nonexistent: no such folder"),
        (["--start", "9,9"], "off the"),
        (["--edges", "fast"], "expected one of"),
    ],
)
def test_bad_flags_name_the_problem(cli, run_dir, tmp_path, args, message):
    base = {"--maze": str(run_dir), "--out": str(tmp_path)}
    for flag, value in zip(args[::2], args[1::2]):
        base[flag] = value
    argv = ["sim", "play"] + [x for kv in base.items() for x in kv]
    result = CliRunner(env={"ROBOTSLANG_BENCHMARK": None}).invoke(cli, argv, input="q\n")
    assert result.exit_code != 0
    # The error panel wraps and frames lines; read it as plain words.
    assert message in " ".join(re.sub("[│╭╮╰╯─]", " ", result.output).split())


def test_the_bundled_maze_is_the_default(cli, tmp_path):
    result = CliRunner(env={"ROBOTSLANG_BENCHMARK": None}).invoke(
        cli, ["sim", "play", "--out", str(tmp_path)], input="a\nq\n"
    )
    assert result.exit_code == 0, result.output
    assert result.output.startswith("gen-000: ")
    assert (tmp_path / "step-001-first-person.png").exists()


def test_a_benchmark_run_by_name(cli, benchmark_path, tmp_path):
    result = CliRunner().invoke(
        cli,
        [
            "sim",
            "play",
            "--maze",
            "Run_318",
            "--benchmark",
            str(benchmark_path),
            "--out",
            str(tmp_path),
            "--start",
            "1.05,1.54,90",
        ],
        input="q\n",
    )
    assert result.exit_code == 0, result.output
    # The hand-checked view of test_observations: the red wall straight ahead, blocking.
    assert "ahead red at 0.131 m (forward blocked)" in result.output

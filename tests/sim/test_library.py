"""The maze library (bundled, local and benchmark mazes by name) and `robotslang mazes`."""

from __future__ import annotations

import json
import re

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from app.cli import root
from sim.cli.mazes import generate_set
from sim.core.labels import Label
from sim.core.maze import FIXED_MAP, Maze, MazeError
from sim.core.validation import check_reachable
from sim.tasks.library import MANIFEST, MazeLibrary, UnknownMazeError
from tests.sim.synthetic import synthetic_maze

BUNDLED = [f"gen-{i:03d}" for i in range(12)]


@pytest.fixture(scope="module")
def local_dir(tmp_path_factory):
    """Two generated mazes in a user's folder, as `robotslang mazes generate` writes them."""
    out = tmp_path_factory.mktemp("local")
    generate_set(out, count=2, seed=40, prefix="mine", progress=False)
    return out


def test_without_the_benchmark_the_bundled_mazes_are_there():
    library = MazeLibrary()
    assert library.names() == BUNDLED
    maze = library.load("gen-003")
    assert maze.name == "gen-003"
    assert set(maze.objects) == {"jar", "mug", "paddle"}
    assert library.load("gen-003") is maze  # read once per library
    assert library.source("gen-003") == "bundled"
    assert library.path("gen-003").name == "gen-003"


def test_every_bundled_maze_loads_and_its_objects_reach_each_other():
    library = MazeLibrary()
    for name in library.names():
        check_reachable(library.load(name))


def test_unknown_name_is_a_key_error_naming_it_and_what_exists():
    library = MazeLibrary()
    with pytest.raises(KeyError) as caught:
        library.load("Run_99999")
    assert isinstance(caught.value, UnknownMazeError)
    assert str(caught.value).startswith("unknown maze 'Run_99999'")
    assert "12 mazes" in str(caught.value) and "gen-000" in str(caught.value)
    with pytest.raises(UnknownMazeError):
        library.source("nope")


def test_with_the_benchmark_its_runs_follow_the_bundled_mazes(benchmark_path):
    library = MazeLibrary(benchmark_path)
    names = library.names()
    assert names[:12] == BUNDLED
    runs = names[12:]
    mazedata = benchmark_path / "mazedata"
    with_map = {d.name for d in mazedata.iterdir() if (d / "maze" / FIXED_MAP).is_file()}
    assert set(runs) == with_map
    assert len(runs) == 172  # 178 runs, 6 of them without a map
    numbers = [int(r.split("_")[1]) for r in runs]
    assert numbers == sorted(numbers)
    maze = library.load("Run_318")
    assert library.source("Run_318") == "benchmark"
    assert maze.labels.shape == (1175, 1401)


def test_benchmark_maps_load_as_published_even_when_objects_are_cut_off(benchmark_path):
    # Run_320's paddle cannot be reached on the benchmark's graph; the paper's figures include
    # it, so the library loads it, while the strict check reports it.
    library = MazeLibrary(benchmark_path)
    maze = library.load("Run_320")
    with pytest.raises(MazeError, match=r"Run_320: .*jar and paddle, mug and paddle"):
        check_reachable(maze)
    check_reachable(library.load("Run_318"))


def test_a_missing_benchmark_folder_is_an_error_naming_it(tmp_path):
    with pytest.raises(FileNotFoundError, match=rf"^{re.escape(str(tmp_path / 'nope'))}: no such folder"):
        MazeLibrary(tmp_path / "nope")
    wide = CliRunner(env={"COLUMNS": "400", "TERMINAL_WIDTH": "400"})  # one line per message
    result = wide.invoke(root, ["mazes", "list", "--benchmark", str(tmp_path / "nope")])
    assert result.exit_code == 2
    assert f"{tmp_path / 'nope'}: no such folder" in result.output


def test_local_folders_come_between_bundled_and_benchmark(local_dir, benchmark_path):
    library = MazeLibrary(benchmark_path, extra_dirs=[local_dir])
    names = library.names()
    assert names[:14] == BUNDLED + ["mine-000", "mine-001"]
    assert library.source("mine-001") == "local"
    assert names[14].startswith("Run_")
    manifest = json.loads((local_dir / MANIFEST).read_text())
    loaded = library.load("mine-001")
    entry = manifest["mazes"][1]
    assert entry["name"] == "mine-001" and entry["seed"] == 41
    for obj, xy in entry["objects"].items():
        assert loaded.objects[obj] == pytest.approx(tuple(xy), abs=1e-3)


def test_a_local_maze_with_unreachable_objects_is_rejected_naming_its_file(tmp_path):
    box = [
        (Label.WHITE, 100, 450, 400, 465),
        (Label.WHITE, 100, 735, 400, 750),
        (Label.WHITE, 100, 450, 115, 750),
        (Label.WHITE, 385, 450, 400, 750),
    ]
    synthetic_maze(rects=box, objects={Label.JAR: (250, 600), Label.MUG: (900, 300), Label.PADDLE: (1100, 900)}).save(
        tmp_path / "boxed"
    )
    library = MazeLibrary(extra_dirs=[tmp_path])
    assert "boxed" in library.names()
    fixed = tmp_path / "boxed" / "maze" / FIXED_MAP
    with pytest.raises(
        MazeError, match=rf"^{re.escape(str(fixed))}: objects cannot reach each other.*: jar and mug, jar and paddle$"
    ):
        library.load("boxed")


def test_a_local_maze_with_an_unknown_colour_is_rejected_naming_its_file(tmp_path):
    folder = MazeLibrary().load("gen-000").save(tmp_path / "odd")
    image = cv2.imread(str(folder / FIXED_MAP))
    image[10:20, 600:610] = (1, 2, 3)
    cv2.imwrite(str(folder / FIXED_MAP), image)
    with pytest.raises(MazeError, match=rf"^{re.escape(str(folder / FIXED_MAP))}: 100 pixels of unknown colour"):
        MazeLibrary(extra_dirs=[tmp_path]).load("odd")


# -- the command line -------------------------------------------------------------------
@pytest.mark.slow
def test_mazes_generate_writes_the_benchmark_layout_and_a_manifest(tmp_path):
    result = CliRunner().invoke(root, ["mazes", "generate", "--count", "2", "--seed", "40", "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    manifest = json.loads((tmp_path / MANIFEST).read_text())
    assert [m["name"] for m in manifest["mazes"]] == ["gen-000", "gen-001"]
    assert [m["seed"] for m in manifest["mazes"]] == [40, 41]
    for entry in manifest["mazes"]:
        maze = Maze.from_dir(tmp_path / entry["name"])
        check_reachable(maze)


def test_mazes_generate_refuses_a_negative_seed(tmp_path):
    result = CliRunner().invoke(root, ["mazes", "generate", "--count", "1", "--seed", "-1", "--out", str(tmp_path)])
    assert result.exit_code != 0
    assert "--seed" in result.output
    assert not any(tmp_path.iterdir())


def test_mazes_list_and_show(tmp_path, local_dir):
    runner = CliRunner(env={"ROBOTSLANG_BENCHMARK": None})  # bundled and local mazes only
    listed = runner.invoke(root, ["mazes", "list", "--dir", str(local_dir)])
    assert listed.exit_code == 0, listed.output
    lines = listed.output.splitlines()
    assert lines[:13] == [f"{n}\tbundled" for n in BUNDLED] + ["mine-000\tlocal"]
    out = tmp_path / "gen-005.png"
    shown = runner.invoke(root, ["mazes", "show", "gen-005", "--out", str(out)])
    assert shown.exit_code == 0, shown.output
    assert np.array_equal(cv2.imread(str(out)), MazeLibrary().load("gen-005").image())
    missing = runner.invoke(root, ["mazes", "show", "Run_0", "--out", str(out)])
    assert missing.exit_code == 1
    assert "unknown maze 'Run_0'" in missing.output

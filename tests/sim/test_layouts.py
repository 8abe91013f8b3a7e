"""Physical layouts: the same tabletop under different maze names is one layout."""

from __future__ import annotations

import json

from typer.testing import CliRunner

from app.cli import root
from sim.core.labels import Label
from sim.tasks.layouts import LayoutSignature, fold_counts, group_layouts, layout_of
from sim.tasks.library import MazeLibrary
from tests.sim.synthetic import synthetic_maze

PX_PER_M = 1400 / 2.4638
WALL = (Label.BLUE, 400, 200, 430, 900)  # a 5 cm thick wall down the table
OBJECTS = {Label.JAR: (700, 300), Label.MUG: (1000, 800), Label.PADDLE: (200, 600)}


def _moved(objects, dx_m: float):
    return {label: (col + round(dx_m * PX_PER_M), row) for label, (col, row) in objects.items()}


def _signatures(**mazes):
    return {
        name: LayoutSignature.of(synthetic_maze(rects, objects, name=name)) for name, (rects, objects) in mazes.items()
    }


def test_landmarks_put_back_nearby_and_walls_redrawn_thinner_are_one_layout():
    thinner = (Label.BLUE, 405, 200, 422, 900)  # 3 cm thick
    found = group_layouts(
        _signatures(a=([WALL], OBJECTS), b=([thinner], _moved(OBJECTS, 0.02)), c=([WALL], _moved(OBJECTS, 0.05)))
    )
    assert [(g.id, g.runs) for g in found] == [("a", ("a", "b", "c"))]


def test_landmarks_elsewhere_or_a_wall_moved_or_added_are_other_layouts():
    moved_wall = (Label.BLUE, 700, 200, 730, 900)
    extra_wall = (Label.RED, 900, 100, 1300, 130)
    found = group_layouts(
        _signatures(
            a=([WALL], OBJECTS),
            far=([WALL], _moved(OBJECTS, 0.15)),
            wall_moved=([moved_wall], OBJECTS),
            wall_added=([WALL, extra_wall], OBJECTS),
        )
    )
    assert [g.runs for g in found] == [("a",), ("far",), ("wall_moved",), ("wall_added",)]


def test_fold_counts_count_layouts_and_the_layouts_two_splits_share():
    of = {"R1": "R1", "R2": "R1", "R3": "R3", "R4": "R4"}
    counts = fold_counts({"train": ["R1", "R1", "R3"], "test": ["R2", "R4"]}, of)
    assert counts == [
        {"split": "train", "instances": 3, "runs": 2, "layouts": 2, "shared_layouts": 1},
        {"split": "test", "instances": 2, "runs": 2, "layouts": 2, "shared_layouts": 1},
    ]


def test_mazes_layouts_prints_every_bundled_maze_once_as_json():
    result = CliRunner(env={"ROBOTSLANG_BENCHMARK": None}).invoke(root, ["mazes", "layouts", "--json"])
    assert result.exit_code == 0, result.output
    layouts = json.loads(result.output)["layouts"]
    runs = [run for layout in layouts for run in layout["runs"]]
    assert sorted(runs) == MazeLibrary().names()
    assert all(layout["id"] == layout["runs"][0] for layout in layouts)
    listed = CliRunner(env={"ROBOTSLANG_BENCHMARK": None}).invoke(root, ["mazes", "list", "--layouts"])
    of = {run: layout["id"] for layout in layouts for run in layout["runs"]}
    assert listed.output.splitlines() == [f"{name}\tbundled\t{of[name]}" for name in MazeLibrary().names()]


def test_benchmark_runs_of_one_table_are_one_layout_and_the_layout_count_is_printed(benchmark_path, capsys):
    library = MazeLibrary(benchmark_path, bundled=None)
    found = library.layouts()
    of = layout_of(found)
    assert {of[r] for r in ("Run_114", "Run_117", "Run_119", "Run_124", "Run_130")} == {"Run_114"}
    # Same walls, landmarks elsewhere; landmarks 3 cm apart, a wall moved: other layouts.
    assert of["Run_146"] != of["Run_152"]
    assert of["Run_202"] != of["Run_203"]
    result = CliRunner().invoke(root, ["mazes", "folds", "--benchmark", str(benchmark_path), "--json"])
    assert result.exit_code == 0, result.output
    folds = json.loads(result.output)
    with capsys.disabled():
        print(
            f"\nbenchmark: {len(library)} runs with a map -> {len(found)} layouts; "
            f"the {folds['runs']} runs of NDH -> {folds['layouts']} layouts"
        )
    assert folds["runs"] == 169
    assert folds["layouts"] == len(
        {of[r] for split in ("train", "val_seen", "test") for r in _runs(benchmark_path, split)}
    )
    assert library.layouts() == found  # the second call reads the cached grouping


def _runs(root, split):
    return {item["scan"].split("/")[-3] for item in json.loads((root / "NDH-data" / f"{split}.json").read_text())}

"""NDH/LDH export: the benchmark's schema and layout, read back by the project's own loader."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from app.export.ndh import assign_splits, ldh_instances, ndh_instances, scan_id, write_benchmark
from sim.tasks.benchmark import Benchmark, NDHInstance
from tests.app.trial_log import maze_named, ndh_trial_record


def test_scan_string_has_the_benchmarks_shape_and_parses():
    scan = scan_id("Run_114", "jar", [0.5900106, 1.7851228, 3.6193362], [2.26156, 0.1785998])
    assert scan == "mazedata/Run_114/maze/maze.labelled.npz-jar-[0.59  1.785 3.619]-[2.262 0.179]"
    inst = NDHInstance.from_json(
        {
            "inst_idx": 0,
            "scan": scan_id("gen-003", "mug", [1, 2], [0.5, 0.25]),
            "target": "mug",
            "agent_pose": [1, 2],
            "target_pose": [0.5, 0.25],
            "all_targets": [[1, 2], [0.5, 0.25], [0, 0]],
            "dialog_history": [],
        }
    )
    assert inst.run == "gen-003" and inst.target == "mug"


def test_one_instance_per_confirmed_target_with_growing_dialog():
    maze = maze_named("m")
    record = ndh_trial_record("1", "m", targets=("mug", "jar", "paddle"), confirmed=2)
    instances = ndh_instances(record, maze)
    assert [i["target"] for i in instances] == ["mug", "jar"]
    first, second = instances
    assert first["agent_pose"] == pytest.approx([0.5, 0.6, 1.5 * math.pi])  # heading in [0, 2 pi)
    assert first["target_pose"] == pytest.approx(maze.objects["mug"])
    assert second["agent_pose"] == pytest.approx(maze.objects["mug"])  # starts at the previous target
    assert [t for t in first["all_targets"]] == [list(maze.objects[t]) for t in ("mug", "jar", "paddle")]
    assert [d["role"] for d in first["dialog_history"]] == ["oracle"] * 2 + ["navigator", "oracle", "navigator"]
    assert first["dialog_history"][-1]["message"] == "found the mug"
    assert second["dialog_history"][: len(first["dialog_history"])] == first["dialog_history"]
    assert second["dialog_history"][-1]["message"] == "found the jar"


def test_without_a_true_start_pose_the_first_target_is_left_out():
    maze = maze_named("m")
    instances = ndh_instances(ndh_trial_record("1", "m", with_pose=False), maze)
    assert [i["target"] for i in instances] == ["mug", "paddle"]
    (ldh,) = ldh_instances(ndh_trial_record("1", "m", with_pose=False), maze)
    assert ldh["agent_pose"] is None and ldh["localization_error_m"] is None


def test_ldh_has_dialog_to_the_estimate_and_its_error():
    maze = maze_named("m")
    (ldh,) = ldh_instances(ndh_trial_record("1", "m"), maze)
    assert [d["message"] for d in ldh["dialog_history"]] == ["hello before the start", "what do you see?", "a red wall"]
    assert ldh["commander_estimate"] == [0.45, 0.5, None]
    assert ldh["agent_pose"][:2] == [0.5, 0.53]
    assert ldh["localization_error_m"] == pytest.approx(math.hypot(0.05, 0.03))


def test_splits_never_share_a_maze_and_train_comes_first():
    assert set(assign_splits(["a"]).values()) == {"train"}
    assert sorted(assign_splits(["a", "b"]).values()) == ["train", "val_seen"]
    folds = assign_splits([f"gen-{i:03d}" for i in range(20)])
    assert sorted(folds.values()).count("test") == 3 and sorted(folds.values()).count("val_seen") == 3
    assert assign_splits(reversed(list(folds))) == folds  # independent of order


def test_export_reads_back_with_the_benchmark_loader(tmp_path):
    mazes = [maze_named(f"gen-{i:03d}", shift=10 * i) for i in range(3)]
    records = [(ndh_trial_record(str(i), m.name), m) for i, m in enumerate(mazes)]
    summary = write_benchmark(records, tmp_path)
    assert sum(summary.ndh.values()) == 9 and all(n == 3 for n in summary.ndh.values())
    bench = Benchmark(tmp_path)
    lookup_scans = json.loads((tmp_path / "lookup_scans.json").read_text())
    seen_idx, runs_by_split = [], {}
    for split in ("train", "val_seen", "test"):
        for inst in bench.split(split):
            seen_idx.append(inst.inst_idx)
            runs_by_split.setdefault(inst.run, set()).add(split)
            assert lookup_scans[inst.scan] == [list(t) for t in inst.all_targets]
            maze = bench.maze(inst.run)
            assert np.array_equal(maze.labels, next(m for m in mazes if m.name == inst.run).labels)
    assert seen_idx == list(range(9))
    assert all(len(s) == 1 for s in runs_by_split.values())
    assert json.loads((tmp_path / "splits.json").read_text()) == summary.splits
    ldh = sum((json.loads((tmp_path / "LDH-data" / f"{s}.json").read_text()) for s in summary.ldh), [])
    assert len(ldh) == 3

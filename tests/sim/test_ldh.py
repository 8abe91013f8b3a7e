"""LDH: the prefix-v1 cut rule, instances derived from the benchmark and read from exports,
and the metrics by hand on a small maze."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from app.cli import root
from sim.core.labels import Label
from sim.core.maze import Maze
from sim.core.navgraph import NavGraph
from sim.language.sectors import Sector
from sim.tasks.benchmark import Benchmark
from sim.tasks.ldh import LDHInstance, Variant, load_split, localization_prefix
from sim.tasks.ldh_eval import MazeContext, MazeContexts, evaluate, score, summarize
from sim.tasks.ldh_features import mentions
from tests.sim.helpers import export_folder, exported, open_table, said


def dialog(*turns):
    return tuple(("oracle" if who == "C" else "navigator", text) for who, text in turns)


def test_prefix_ends_before_the_first_movement_instruction():
    d = dialog(
        ("C", "What do you see?"),
        ("D", "a yellow wall ahead, red to my left"),
        ("C", "if you back up a little, is there a red wall to your left?"),
        ("D", "yes"),
        ("C", "Ok make a left at the red wall"),
        ("D", "done"),
    )
    assert localization_prefix(d) == 4  # the question about backing up is still localization


def test_prefix_keeps_the_commander_saying_they_know_where_the_robot_is():
    d = dialog(
        ("C", "Describe your surroundings"),
        ("D", "blue walls on my right"),
        ("C", "Ok I know where you are"),
        ("C", "go forward"),
    )
    assert localization_prefix(d) == 3


def test_prefix_ignores_driver_moves_and_keeps_everything_without_a_cue():
    d = dialog(("D", "Go ahead and tell me where to go"), ("C", "what is behind you?"), ("D", "white"))
    assert localization_prefix(d) == 3


def test_mentions_put_each_colour_in_the_sector_of_its_clause():
    counts = mentions(
        dialog(("D", "a red wall to my left and yellow ahead"), ("C", "blue on your right?"), ("D", "green walls"))
    )
    assert counts[Sector.LEFT, Label.RED] == 1 and counts[Sector.FRONT, Label.YELLOW] == 1
    assert counts[Sector.ANY, Label.GREEN] == 1 and counts[:, Label.BLUE].sum() == 0  # Commander's words
    assert counts.sum() == 3


@pytest.fixture(scope="module")
def open_ctx():
    graph = NavGraph.build(Maze.from_labels(open_table(), "open"), "benchmark")
    return MazeContext("open", graph, views=np.zeros((graph.n, 8, 4, 10, 2), np.float32))


def instance_at(x, y, idx=0, run="open"):
    return LDHInstance(inst_idx=idx, run=run, x=x, y=y, heading=0.0, dialog=(), variant=Variant.PREFIX)


def test_td_euclid_and_accuracy_by_hand(open_ctx):
    g = open_ctx.graph
    truth = instance_at(1.4, 0.7)
    # Ten axis steps of 0.07 m due west of the truth: TD = Euclid = 0.7 m, within 1 m only.
    td, euclid, acc = score(open_ctx, open_ctx.one_hot(g.nearest_node(0.7, 0.7)), truth)
    assert td == pytest.approx(0.7) and euclid == pytest.approx(0.7) and acc == (0.0, 0.0, 1.0)
    # Half on the truth, half 0.28 m north: expectations 0.14 m, within 0.25 m half the time.
    belief = (open_ctx.one_hot(g.nearest_node(1.4, 0.7)) + open_ctx.one_hot(g.nearest_node(1.4, 0.98))) / 2
    td, euclid, acc = score(open_ctx, belief, truth)
    assert td == pytest.approx(0.14) and euclid == pytest.approx(0.14) and acc == (0.5, 1.0, 1.0)


def test_random_is_the_exact_mean_over_the_main_component(open_ctx):
    truth = instance_at(1.4, 0.7)
    td, _, _ = score(open_ctx, open_ctx.uniform(), truth)
    true = open_ctx.graph.nearest_node(1.4, 0.7)
    assert open_ctx.main.all()  # an open table is one component
    assert td == pytest.approx(open_ctx.graph.dist[:, true].mean())


def test_center_minimises_the_mean_td(open_ctx):
    d = open_ctx.graph.dist
    assert d[open_ctx.center].mean() == pytest.approx(d.mean(axis=1).min())
    assert np.allclose(open_ctx.graph.nodes[open_ctx.center], [1.19, 1.05], atol=0.08)  # the table's middle


def test_summary_shape_and_sample_std(open_ctx, tmp_path):
    class Contexts(MazeContexts):
        def __getitem__(self, run):
            return open_ctx

    insts = [instance_at(1.4, 0.7), instance_at(1.4, 0.98, idx=1)]
    stay = lambda inst, ctx: ctx.one_hot(ctx.graph.nearest_node(1.4, 0.7))  # noqa: E731
    results = evaluate(None, "val_seen", insts, {"stay": stay}, contexts=Contexts(None))
    s = summarize("val_seen", "prefix", 2, results)
    assert set(s) == {"split", "variant", "n", "agents"}
    a = s["agents"]["stay"]
    assert set(a) == {"td_mean", "td_std", "td_median", "euclid_mean", "acc_0.25", "acc_0.5", "acc_1.0"}
    assert a["td_mean"] == pytest.approx(0.14) and a["td_std"] == pytest.approx(np.std([0, 0.28], ddof=1))
    assert a["td_median"] == pytest.approx(0.14)
    assert a["acc_0.25"] == 0.5 and a["acc_1.0"] == 1.0


def test_the_evaluator_reads_exported_trials_and_skips_those_without_a_true_pose(tmp_path):
    root_dir = export_folder(tmp_path, [exported(0, [1.4, 0.7, 0.0]), exported(1, None)])
    (inst,) = load_split(Benchmark(root_dir), "val_seen")
    assert inst.variant == Variant.EXACT and inst.run == "m1" and (inst.x, inst.y) == (1.4, 0.7)
    result = CliRunner().invoke(
        root, ["eval", "ldh", "--benchmark", str(root_dir), "--split", "val_seen", "--agent", "random,center", "--json"]
    )
    assert result.exit_code == 0, result.output
    out = json.loads(result.output)
    assert out["variant"] == "exact" and out["n"] == 1 and set(out["agents"]) == {"random", "center"}


def test_an_empty_split_is_a_clear_error(tmp_path):
    root_dir = export_folder(tmp_path, [])
    result = CliRunner().invoke(root, ["eval", "ldh", "--benchmark", str(root_dir), "--split", "val_seen", "--json"])
    assert result.exit_code == 2 and "no LDH instances" in said(result)


def test_an_unknown_agent_is_a_clear_error(tmp_path):
    result = CliRunner().invoke(
        root, ["eval", "ldh", "--benchmark", str(export_folder(tmp_path, [])), "--agent", "oracle"]
    )
    assert result.exit_code == 2 and "unknown agent oracle" in said(result)


@pytest.mark.benchmark_data
def test_one_instance_per_trial_from_the_benchmark(benchmark_path):
    bench = Benchmark(benchmark_path)
    ndh = {inst.inst_idx: inst for inst in bench.split("val_seen")}
    prefix = load_split(bench, "val_seen", Variant.PREFIX)
    full = load_split(bench, "val_seen", Variant.FULL)
    assert len(prefix) == len(full) == 26  # one trial per jar instance
    for p, f in zip(prefix, full):
        source = ndh[p.inst_idx]
        assert source.target == "jar" and (p.x, p.y, p.heading) == tuple(source.agent_pose)
        assert f.dialog == source.dialog and p.dialog == f.dialog[: len(p.dialog)]
        assert 0 < len(p.dialog) < len(f.dialog)

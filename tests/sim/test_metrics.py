"""TD, OTD, SR and SPL by hand, and the summary's JSON and CSV shapes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.core.maze import Maze
from sim.core.metrics import CSV_COLUMNS, EpisodeResult, read_csv, score_trajectory, summarize, write_csv
from sim.core.navgraph import NavGraph
from tests.sim.helpers import open_table, wall_at_x


@pytest.fixture(scope="module")
def graph():
    return NavGraph.build(Maze.from_labels(open_table(), "open"), "exact", use_cache=False)


def row(g, *xs, y=0.7):
    return [g.nearest_node(x, y) for x in xs]


def test_td_otd_success_and_spl_by_hand(graph):
    goal = graph.nearest_node(0.7 + 10 * 0.07, 0.7)
    # Walk 9 steps east: 0.07 m from the goal, within 0.508 m: success with SPL 1.
    path = row(graph, *[0.7 + k * 0.07 for k in range(10)])
    s = score_trajectory(graph, path, goal)
    assert s.td == pytest.approx(0.07) and s.otd == pytest.approx(0.07)
    assert s.success and s.spl == pytest.approx(0.7 / 0.7 * 1.0) and s.shortest == pytest.approx(0.7)
    # Overshoot by 3 steps then come back 1: OTD is 0 at the goal, TD 0.14, path 0.7 + 0.21 + 0.07.
    there = [0.7 + k * 0.07 for k in range(14)] + [0.7 + 12 * 0.07]
    s = score_trajectory(graph, row(graph, *there), goal)
    assert s.otd == pytest.approx(0.0) and s.td == pytest.approx(0.14)
    assert s.success and s.spl == pytest.approx(0.7 / (0.7 + 0.21 + 0.07))
    # Stop right away 0.7 m away: no success, SPL 0.
    s = score_trajectory(graph, row(graph, 0.7), goal)
    assert s.td == pytest.approx(0.7) and not s.success and s.spl == 0.0


def result(inst, agent, seed, td, steps=0, success=False, spl=0.0):
    return EpisodeResult("val_seen", inst, agent, seed, 0, 0, 0, 1, 1, td, td, steps, success, spl)


def test_summary_averages_seeds_per_instance_then_uses_sample_std():
    results = [
        result(1, "random", 0, 2.0),
        result(1, "random", 1, 4.0),  # instance mean 3
        result(2, "random", 0, 5.0),
        result(2, "random", 1, 5.0),  # instance mean 5
        result(1, "stop", 0, 1.0, success=False),
        result(2, "stop", 0, 0.2, success=True, spl=0.5),
    ]
    s = summarize("val_seen", results)
    assert s["split"] == "val_seen" and s["n"] == 2
    r = s["agents"]["random"]
    assert r["td_mean"] == pytest.approx(4.0) and r["td_std"] == pytest.approx(np.std([3, 5], ddof=1))
    assert s["agents"]["stop"]["sr"] == 0.5 and s["agents"]["stop"]["spl"] == 0.25
    assert set(r) >= {"td_mean", "td_std", "otd_mean", "otd_std", "sr", "spl", "steps_mean"}


def test_unreachable_goals_are_counted_not_averaged():
    s = summarize("test", [result(1, "stop", 0, math.inf), result(2, "stop", 0, 3.0), result(3, "stop", 0, 1.0)])
    stop = s["agents"]["stop"]
    assert stop["unreachable"] == 1 and stop["td_mean"] == pytest.approx(2.0)


def test_csv_round_trip(tmp_path):
    rows = [result(7, "shortest", 2, 0.0, steps=40, success=True, spl=1.0)]
    write_csv(tmp_path / "r.csv", rows)
    assert (tmp_path / "r.csv").read_text().splitlines()[0] == ",".join(CSV_COLUMNS)
    assert read_csv(tmp_path / "r.csv") == rows


def test_walls_make_goals_unreachable_with_infinite_td():
    g = NavGraph.build(Maze.from_labels(wall_at_x(open_table(), 1.0), "walled"), use_cache=False)
    s = score_trajectory(g, [g.nearest_node(0.5, 1.0)], g.nearest_node(1.5, 1.0))
    assert s.td == math.inf and not s.success and s.spl == 0.0

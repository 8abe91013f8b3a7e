"""Paired t-tests over instances (seeds averaged first) with the Benjamini-Yekutieli correction,
against figures worked out by hand."""

from __future__ import annotations

import math

import pytest
from scipy import stats as scipy_stats

from models.stats import paired_tests
from sim.metrics import EpisodeResult


def result(agent, inst, seed, td):
    return EpisodeResult(split="test", inst_idx=inst, agent=agent, seed=seed, start_x=0, start_y=0, start_heading=0,
                         goal_x=0, goal_y=0, td=td, otd=td, steps=1, success=False, spl=0.0)


# Per-instance TDs; "full" has two seeds whose means are 2, 3, 4, 5.
FULL = {0: (1.5, 2.5), 1: (3.0, 3.0), 2: (4.5, 3.5), 3: (5.0, 5.0)}
BLIND = {0: 3.0, 1: 3.5, 2: 5.5, 3: 6.0}  # differences from full: 1.0, 0.5, 1.5, 1.0
OTHER = {0: 2.5, 1: 2.0, 2: 4.5, 3: 5.0}  # differences from full: 0.5, -1.0, 0.5, 0.0


def results():
    out = [result("full", k, s, td) for k, tds in FULL.items() for s, td in enumerate(tds)]
    out += [result("blind", k, 0, td) for k, td in BLIND.items()]
    out += [result("other", k, 0, td) for k, td in OTHER.items()]
    return out


def test_paired_t_and_by_correction_match_the_hand_computation():
    blind, other = paired_tests(results(), [("full", "blind"), ("full", "other")])
    # full - blind = -1.0, -0.5, -1.5, -1.0: mean -1, sample sd sqrt(0.5/3), t = -1 / (sd / 2) = -4.899
    assert blind.n == 4 and blind.mean_a == 3.5 and blind.mean_b == 4.5
    assert blind.t == pytest.approx(-1 / (math.sqrt(0.5 / 3) / 2))
    p_blind = 2 * scipy_stats.t.sf(abs(blind.t), df=3)
    assert blind.p == pytest.approx(p_blind)
    # full - other = -0.5, 1.0, -0.5, 0.0: mean 0, t = 0, p = 1
    assert other.t == pytest.approx(0.0, abs=1e-12) and other.p == pytest.approx(1.0)
    # BY with m = 2: c(m) = 1 + 1/2 = 1.5; smallest p * 2 * 1.5 / 1, largest p * 2 * 1.5 / 2 (capped at 1).
    assert blind.p_adjusted == pytest.approx(p_blind * 3)
    assert other.p_adjusted == pytest.approx(1.0)
    assert blind.p_adjusted == pytest.approx(0.0489, abs=5e-4)  # p = 0.01628
    assert blind.significant and not other.significant


def test_unknown_configuration_is_named():
    with pytest.raises(ValueError, match="'missing'"):
        paired_tests(results(), [("full", "missing")])

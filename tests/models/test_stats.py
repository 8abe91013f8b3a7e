"""Paired t-tests over instances (seeds averaged first) with the Benjamini-Yekutieli correction,
against figures worked out by hand."""

from __future__ import annotations

import math

import pytest
from scipy import stats as scipy_stats

from models.stats import paired_tests, seed_tests
from sim.core.metrics import EpisodeResult


def result(agent, inst, seed, td):
    return EpisodeResult(
        split="test",
        inst_idx=inst,
        agent=agent,
        seed=seed,
        start_x=0,
        start_y=0,
        start_heading=0,
        goal_x=0,
        goal_y=0,
        td=td,
        otd=td,
        steps=1,
        success=False,
        spl=0.0,
    )


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


def seeded(agent, per_seed_tds):
    return [result(agent, inst, seed, td) for seed, tds in enumerate(per_seed_tds) for inst, td in enumerate(tds)]


def test_seed_test_pairs_per_seed_means_by_hand():
    # a's seeds average 2, 3, 4 over their instances; b's 3, 3.5, 5: differences -1, -0.5, -1.
    rs = seeded("a", [(1.0, 3.0), (2.0, 4.0), (4.0, 4.0)]) + seeded("b", [(3.0, 3.0), (3.0, 4.0), (6.0, 4.0)])
    (c,) = seed_tests(rs, [("a", "b")])
    assert c.unit == "seed" and c.n == 3 and c.mean_a == 3.0 and c.mean_b == pytest.approx(11.5 / 3)
    d = [-1.0, -0.5, -1.0]
    sd = math.sqrt(sum((x - sum(d) / 3) ** 2 for x in d) / 2)
    assert c.t == pytest.approx((sum(d) / 3) / (sd / math.sqrt(3)))
    assert c.p == pytest.approx(2 * scipy_stats.t.sf(abs(c.t), df=2))
    assert c.p_adjusted == pytest.approx(c.p)  # a family of one


def test_a_gain_carried_by_one_seed_holds_over_instances_but_not_over_seeds():
    # 20 instances; a beats b by 1 m on seed 0 only, and is 0.1 m worse on seeds 1 and 2.
    base = [2.0 + 0.1 * k for k in range(20)]
    a = [[t - 1.0 + 0.05 * (k % 3) for k, t in enumerate(base)], [t + 0.1 for t in base], [t + 0.1 for t in base]]
    b = [base, base, base]
    rs = seeded("a", a) + seeded("b", b)
    (over_instances,) = paired_tests(rs, [("a", "b")])
    (over_seeds,) = seed_tests(rs, [("a", "b")])
    assert over_instances.unit == "instance" and over_instances.n == 20 and over_instances.significant
    assert over_seeds.n == 3 and not over_seeds.significant


def test_seed_test_needs_two_seeds():
    with pytest.raises(ValueError, match="two seeds"):
        seed_tests(seeded("a", [(1.0, 2.0)]) + seeded("b", [(2.0, 3.0)]), [("a", "b")])

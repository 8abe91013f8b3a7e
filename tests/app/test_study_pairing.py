"""The team plan's pairing rule, on its own: new partners first, roles balanced, never a layout
either has seen, and nobody past the plan's teams."""

from __future__ import annotations

from app.study.pairing import History, Pair, next_pair

POOL = {"L1", "L2", "L3"}


def who(pid: int, partners=(), commanded: int = 0, drove: int = 0, layouts=()) -> History:
    return History(pid, frozenset(partners), commanded, drove, frozenset(layouts))


def test_a_new_partner_comes_before_an_old_one_who_waited_longer():
    ann = who(1, partners={2})
    waiting = [who(2, partners={1}), who(3)]
    pair = next_pair(ann, waiting, POOL, teams_per_participant=5)
    assert pair is not None and 3 in (pair.commander, pair.driver)


def test_an_old_partner_when_no_one_new_waits_and_otherwise_the_longest_waiting():
    ann = who(1, partners={2})
    assert next_pair(ann, [who(2, partners={1})], POOL, 5) is not None
    pair = next_pair(who(1), [who(4), who(3)], POOL, 5)
    assert pair is not None and 4 in (pair.commander, pair.driver), "4 waited longer than 3"


def test_the_one_who_has_commanded_more_drives_and_on_a_tie_the_longer_waiting_commands():
    assert next_pair(who(1, commanded=2, drove=1), [who(2, drove=1)], POOL, 5) == Pair(commander=2, driver=1)
    assert next_pair(who(1, drove=2), [who(2, commanded=1)], POOL, 5) == Pair(commander=1, driver=2)
    assert next_pair(who(1, commanded=1, drove=1), [who(2)], POOL, 5) == Pair(commander=2, driver=1)


def test_never_a_layout_either_has_seen():
    ann = who(1, layouts={"L1", "L2"})
    assert next_pair(ann, [who(2, layouts={"L3"})], POOL, 5) is None, "no layout left for both"
    pair = next_pair(ann, [who(2, layouts={"L3"}), who(3, layouts={"L1"})], POOL, 5)
    assert pair is not None and 3 in (pair.commander, pair.driver)


def test_no_pairing_for_a_participant_who_reached_the_plans_teams():
    done = who(1, partners={7, 8})
    assert next_pair(done, [who(2)], POOL, teams_per_participant=2) is None
    pair = next_pair(who(2), [done, who(3)], POOL, teams_per_participant=2)
    assert pair is not None and 1 not in (pair.commander, pair.driver)
    assert next_pair(who(2), [done], POOL, teams_per_participant=2) is None

"""The team plan's pairing rule, on its own (the lobby uses it: tests/app/test_study.py)."""

from app.study.plan import History, Pairing, choose_pair

LAYOUTS = frozenset({"L1", "L2", "L3"})


def who(pid: int, partners=(), commanded=0, driven=0, seen=()) -> History:
    return History(pid, frozenset(partners), commanded, driven, frozenset(seen))


def test_a_new_partner_is_preferred_over_one_who_waited_longer():
    me = who(1, partners={2}, commanded=1)
    known, new = who(2, partners={1}, driven=1), who(3)
    assert choose_pair(me, [known, new], LAYOUTS, 5) == Pairing(commander_id=3, driver_id=1)


def test_a_known_partner_is_taken_when_no_new_one_waits():
    me = who(1, partners={2}, driven=1)
    assert choose_pair(me, [who(2, partners={1}, commanded=1)], LAYOUTS, 5) == Pairing(1, 2)


def test_whoever_commanded_more_drives_and_on_a_tie_who_waited_longer_commands():
    assert choose_pair(who(1, commanded=2, driven=1), [who(2, commanded=1)], LAYOUTS, 5) == Pairing(2, 1)
    assert choose_pair(who(1, driven=2), [who(2, commanded=1, driven=1)], LAYOUTS, 5) == Pairing(1, 2)
    assert choose_pair(who(1), [who(2)], LAYOUTS, 5) == Pairing(2, 1)


def test_no_pair_without_a_layout_neither_has_seen():
    me = who(1, seen={"L1", "L2"})
    assert choose_pair(me, [who(2, seen={"L3"})], LAYOUTS, 5) is None
    assert choose_pair(me, [who(2, seen={"L3"}), who(3, seen={"L1"})], LAYOUTS, 5) == Pairing(3, 1)


def test_no_new_team_for_a_participant_who_has_their_number_of_teams():
    full = who(1, partners={2, 3})
    assert choose_pair(full, [who(4)], LAYOUTS, 2) is None
    assert choose_pair(who(4), [full], LAYOUTS, 2) is None, "nor for their partner-to-be"
    assert choose_pair(full, [who(4), who(3, partners={1})], LAYOUTS, 2) == Pairing(3, 1)
    assert choose_pair(full, [who(4)], LAYOUTS, 3) == Pairing(4, 1)

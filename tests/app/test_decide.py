"""The trial's rules, `decide(state, command) -> events`, on states folded from real-shaped logs."""

from __future__ import annotations

import pytest

from sim.trial import events as ev
from sim.trial.commands import Abort, Act, Claim, FinishMove, Join, Leave, Now, Reopen, RequestMove, Say
from sim.trial.decide import Refused, decide
from sim.trial.state import LoggedEvent, fold
from sim.trial.vocabulary import Move, Outcome, Phase, Role

S = 1_000_000_000
CREATED = {"maze": "m", "targets": ["jar", "mug", "paddle"], "backend": "sim", "driver": "human"}


def running(*extra):
    items = [
        ("trial_created", CREATED),
        ("connect", {"role": "commander"}),
        ("connect", {"role": "driver"}),
        ("phase", {"phase": "localizing", "target_index": 0}),
        *extra,
    ]
    return fold(LoggedEvent(i + 1, kind, i * S, payload) for i, (kind, payload) in enumerate(items))


def test_both_seats_in_starts_the_trial():
    state = fold([LoggedEvent(1, "trial_created", 0, CREATED), LoggedEvent(2, "connect", S, {"role": "commander"})])
    assert decide(state, Join(Role.DRIVER)) == [
        ev.Connected(role=Role.DRIVER),
        ev.PhaseChanged(phase=Phase.LOCALIZING, target_index=0),
    ]


def test_a_move_id_is_executed_once():
    state = running(
        ("move_requested", {"move_id": "m1", "action": "left"}),
        ("move_executed", {"move_id": "m1", "action": "left", "outcome": "ok", "collision": False}),
    )
    with pytest.raises(Refused, match="already received"):
        decide(state, Act(Role.DRIVER, RequestMove(Move.LEFT, "m1"), Now(t_ns=100 * S)))
    assert decide(state, Act(Role.DRIVER, RequestMove(Move.LEFT, "m2"), Now(t_ns=100 * S))) == [
        ev.MoveRequested(move_id="m2", action=Move.LEFT)
    ]


def test_a_move_asked_too_soon_is_refused_without_spending_its_id():
    state = running(
        ("move_requested", {"move_id": "m1", "action": "left"}),
        ("move_executed", {"move_id": "m1", "action": "left", "outcome": "ok", "collision": False}),
    )
    soon = Act(
        Role.DRIVER, RequestMove(Move.LEFT, "m2"), Now(t_ns=state.last_move_ns + S // 10, min_move_interval_ns=S // 4)
    )
    assert decide(state, soon) == [ev.MovesRefused(reason="too soon after the previous move")]
    later = Act(
        Role.DRIVER, RequestMove(Move.LEFT, "m2"), Now(t_ns=state.last_move_ns + S, min_move_interval_ns=S // 4)
    )
    assert decide(state, later) == [ev.MoveRequested(move_id="m2", action=Move.LEFT)]


def test_reopening_refuses_the_move_in_flight_and_lets_the_seats_go():
    state = running(("move_requested", {"move_id": "m1", "action": "forward"}))
    events = decide(state, Reopen())
    assert events[0] == ev.Restarted(paused=["disconnect:commander", "disconnect:driver"])
    assert (
        ev.MoveExecuted(move_id="m1", action=Move.FORWARD, outcome=Outcome.REFUSED, reason="server restart") in events
    )
    assert {e.role for e in events if isinstance(e, ev.Disconnected)} == {Role.COMMANDER, Role.DRIVER}
    assert decide(state, FinishMove("m1", Outcome.OK)) == [
        ev.MoveExecuted(move_id="m1", action=Move.FORWARD, outcome=Outcome.OK)
    ]


def test_an_ended_trial_takes_nothing_more():
    state = running(("phase", {"phase": "aborted", "target_index": None}))
    assert decide(state, Reopen()) == [] and decide(state, Leave(Role.DRIVER)) == [] and decide(state, Abort()) == []
    with pytest.raises(Refused, match="aborted"):
        decide(state, Act(Role.DRIVER, Say("hello?")))


def test_an_abort_logs_its_reason_and_a_log_without_one_still_folds():
    (aborted,) = decide(running(), Abort("agent Driver's cap: 300 moves for target 1"))
    assert aborted.payload() == {
        "phase": "aborted",
        "target_index": None,
        "reason": "agent Driver's cap: 300 moves for target 1",
    }
    assert "reason" not in decide(running(), Abort())[0].payload()  # the experimenter's abort: as before
    for payload in (aborted.payload(), {"phase": "aborted", "target_index": None}):  # a log from before reasons
        state = running(("phase", payload))
        assert state.phase == Phase.ABORTED and state.over


def test_a_seat_takes_only_its_own_actions():
    state = running()
    with pytest.raises(Refused, match="may not send 'move'"):
        decide(state, Act(Role.COMMANDER, RequestMove(Move.FORWARD)))
    with pytest.raises(Refused, match="may not send 'claim'"):
        decide(state, Act(Role.COMMANDER, Claim()))
    assert decide(state, Act(Role.COMMANDER, Say("hello"))) == [ev.Chat(role=Role.COMMANDER, text="hello")]

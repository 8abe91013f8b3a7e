"""The fold from events to trial state: phases, the trial clock and the score."""

from __future__ import annotations

from sim.trial.state import LoggedEvent, fold

S = 1_000_000_000


def log(*items):
    return [LoggedEvent(i + 1, kind, t * S, payload) for i, (t, kind, payload) in enumerate(items)]


CREATED = {"maze": "m", "targets": ["jar", "mug", "paddle"], "backend": "sim", "driver": "human"}


def test_clock_runs_only_while_playing_and_stops_when_paused():
    events = log(
        (0, "trial_created", CREATED),
        (5, "phase", {"phase": "localizing", "target_index": 0}),
        (15, "paused", {"reason": "disconnect:driver"}),
        (45, "resumed", {"reason": "disconnect:driver"}),
        (50, "phase", {"phase": "navigating", "target_index": 0}),
    )
    state = fold(events)
    assert state.active_s() == 15.0
    assert state.active_s(now_ns=60 * S) == 25.0
    assert state.current_target == "jar" and state.running


def test_score_is_time_to_last_confirmation_plus_move_penalty():
    events = log(
        (0, "trial_created", CREATED),
        (1, "phase", {"phase": "localizing", "target_index": 0}),
        (2, "move_executed", {"move_id": "a", "action": "forward", "outcome": "ok", "collision": False}),
        (3, "move_executed", {"move_id": "b", "action": "forward", "outcome": "collision", "collision": True}),
        (
            4,
            "move_executed",
            {
                "move_id": "c",
                "action": "left",
                "outcome": "refused",
                "collision": False,
                "reason": "too soon after the previous move",
            },
        ),
        (4, "moves_refused", {"reason": "the previous move is still executing", "count": 7}),
        (5, "target_claimed", {"target": "jar", "target_index": 0, "frame_id": 9}),
        (6, "target_confirmed", {"target": "jar", "target_index": 0}),
        (31, "phase", {"phase": "finished", "target_index": 3}),
    )
    state = fold(events)
    assert state.moves == 2 and state.collisions == 1 and state.pending_claim is None
    assert state.refused == 1 + 7  # the robot's refusal and a run of seven refused as they came
    assert state.score(move_penalty_s=1.0) == 32.0
    assert state.score(move_penalty_s=0.5) == 31.0


def test_unfinished_trials_do_not_score():
    events = log(
        (0, "trial_created", CREATED),
        (1, "phase", {"phase": "localizing", "target_index": 0}),
        (9, "phase", {"phase": "aborted", "target_index": None}),
    )
    state = fold(events)
    assert state.over and state.score(1.0) is None and state.active_s() == 8.0


def test_the_clock_stops_at_the_last_event_before_a_server_restart():
    events = log(
        (0, "trial_created", CREATED),
        (1, "phase", {"phase": "localizing", "target_index": 0}),
        (4, "chat", {"role": "commander", "text": "hi"}),
        # the server died here; it came back 600 s later
        (604, "restarted", {"paused": ["disconnect:driver"]}),
        (605, "disconnect", {"role": "driver"}),
        (610, "connect", {"role": "driver"}),
        (610, "resumed", {"reason": "disconnect:driver"}),
    )
    state = fold(events)
    assert state.active_s() == 3.0
    assert state.active_s(now_ns=612 * S) == 5.0


def test_a_seat_away_before_a_restart_keeps_the_time_it_was_away():
    events = log(
        (0, "trial_created", CREATED),
        (1, "phase", {"phase": "localizing", "target_index": 0}),
        (10, "disconnect", {"role": "driver"}),
        (10, "paused", {"reason": "disconnect:driver"}),
        (40, "chat", {"role": "commander", "text": "are you there?"}),
        (900, "restarted", {}),
    )
    state = fold(events)
    assert state.away["driver"].away_ns(905 * S) == 35 * S  # 30 s before the crash, 5 s after it

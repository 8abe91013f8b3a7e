"""`EventLog`'s group commit, on the loop and on its writer thread, on SQLite and PostgreSQL:
nothing is heard before it is committed, seats hear in the order events were appended, and one
trial's conflict costs the other trials nothing."""

from __future__ import annotations

import asyncio

import pytest
from sqlalchemy import func, select

from app.db.engine import make_engine, make_sessionmaker, upgrade
from app.db.models import Event
from app.trial.log import EventLog
from bench.live import team_trial
from sim.trial.state import LoggedEvent
from tests.app.live import platform_settings

MAZE = "gen-000"
TRIALS = 3
TURNS = 20


def new_trials(sessions, n: int) -> list[int]:
    """`n` trials of `n` teams (a team plays each maze once)."""
    with sessions.begin() as db:
        return [team_trial(db, f"team {i}", MAZE, [MAZE], 0) for i in range(n)]


def committed_count(sessions, trial_id: int) -> int:
    with sessions() as db:
        return db.scalar(select(func.count()).select_from(Event).where(Event.trial_id == trial_id))


@pytest.mark.parametrize("writer_thread", [False, True], ids=["on the loop", "writer thread"])
def test_seats_hear_only_committed_events_in_append_order(any_db_settings, writer_thread):
    engine = make_engine(any_db_settings)
    upgrade(any_db_settings, engine)
    sessions = make_sessionmaker(engine)
    trial_ids = new_trials(sessions, TRIALS)
    log = EventLog(sessions, writer_thread=writer_thread)
    heard: list[tuple[int, int]] = []
    lost: list[int] = []
    log.on_lost = lambda trial_id, err: lost.append(trial_id)

    def hear(trial_id: int, seq: int) -> None:
        # From a connection of its own: the event must already be in the database.
        assert committed_count(sessions, trial_id) >= seq
        heard.append((trial_id, seq))

    async def play() -> None:
        for turn in range(1, TURNS + 1):
            for trial_id in trial_ids:
                seq = turn + 1  # seq 1: the trial's creation
                log.append(trial_id, LoggedEvent(seq, "chat", seq, {"text": f"turn {turn}"}))
                log.after_commit(trial_id, hear, trial_id, seq)
            await asyncio.sleep(0)  # the end of a turn: a batch goes to commit
        while len(heard) + len(lost) < TRIALS * TURNS:
            await asyncio.sleep(0.01)
        log.close()

    asyncio.run(asyncio.wait_for(play(), 120))
    assert lost == []
    assert heard == [(t, turn + 1) for turn in range(1, TURNS + 1) for t in trial_ids]
    assert [e.seq for e in log.load(trial_ids[0])] == list(range(1, TURNS + 2))
    engine.dispose()


@pytest.mark.parametrize("writer_thread", [False, True], ids=["on the loop", "writer thread"])
def test_a_conflicting_trial_loses_only_its_own_batch(any_db_settings, writer_thread):
    engine = make_engine(any_db_settings)
    upgrade(any_db_settings, engine)
    sessions = make_sessionmaker(engine)
    mine, theirs = new_trials(sessions, 2)
    EventLog(sessions).append(theirs, LoggedEvent(2, "chat", 1, {"text": "another process wrote this"}))
    log = EventLog(sessions, writer_thread=writer_thread)
    heard: list[int] = []
    lost: list[int] = []
    log.on_lost = lambda trial_id, err: lost.append(trial_id)

    async def play() -> None:
        log.append(mine, LoggedEvent(2, "chat", 1, {"text": "mine"}))
        log.after_commit(mine, heard.append, mine)
        log.append(theirs, LoggedEvent(2, "chat", 2, {"text": "a seq already taken"}))
        log.after_commit(theirs, heard.append, theirs)
        while not (heard and lost):
            await asyncio.sleep(0.01)
        log.close()

    asyncio.run(asyncio.wait_for(play(), 120))
    assert heard == [mine] and lost == [theirs]
    assert [e.payload.get("text") for e in log.load(mine)][1:] == ["mine"]
    assert [e.payload.get("text") for e in log.load(theirs)][1:] == ["another process wrote this"]
    engine.dispose()


@pytest.mark.parametrize("writer_thread", [False, True], ids=["on the loop", "writer thread"])
def test_a_read_commits_only_when_its_own_trial_has_events_waiting(tmp_path, writer_thread):
    settings = platform_settings(tmp_path)
    engine = make_engine(settings)
    upgrade(settings, engine)
    sessions = make_sessionmaker(engine)
    busy, reader = new_trials(sessions, 2)
    log = EventLog(sessions, writer_thread=writer_thread)

    async def play() -> tuple[list[int], int, list[int], int]:
        log.append(busy, LoggedEvent(2, "chat", 2, {"text": "waiting for the turn's commit"}))
        other = [e.seq for e in log.load(reader)]  # another trial's read: nothing of `busy` committed
        waiting = committed_count(sessions, busy)
        own = [e.seq for e in log.load(busy)]  # its own read sees what it appended
        done = committed_count(sessions, busy)
        log.close()
        return other, waiting, own, done

    other, waiting, own, done = asyncio.run(play())
    assert other == [1] and waiting == 1
    assert own == [1, 2] and done == 2
    engine.dispose()

"""A study's participants on every path through it, over HTTP and websockets against a real server:
a restarted trial stays in the study and their seat pages are sent on to it; one who leaves the
lobby is not paired, and a paired seat counts down to its partner's join deadline."""

from __future__ import annotations

import asyncio
import html

from sqlalchemy import select

from app.db.models import Participant, Trial
from app.study.config import StudyFiles, template
from app.study.lobby import PRACTICE_REASON
from bench.live import SeatClient
from tests.app.live import browser, experimenter_client, open_seats
from tests.app.test_study import join, poll


def pool_of_two(server) -> list[str]:
    """Two mazes of different layouts, the last the library names (a restart outside the pool
    would take the least-used layout: one of the first)."""
    layouts = server.services.mazes.layouts()
    pool: dict[str, str] = {}
    for maze in reversed(server.services.mazes.names()):
        pool.setdefault(layouts[maze], maze)
        if len(pool) == 2:
            return sorted(pool.values())
    raise AssertionError("the library has fewer than two layouts")


def created(server, trial_id: int) -> dict:
    return server.services.log.load(trial_id)[0].payload


def test_a_restarted_study_trial_stays_in_the_study_and_the_seat_pages_follow_it(server):
    pool = pool_of_two(server)
    plan = {"practice_maze": None, "maze_pool": pool, "join_timeout_s": 45.0}
    StudyFiles.of(server.settings.data_dir).save(template("pilot").model_copy(update=plan))
    (ann, ann_code), (bob, bob_code) = join(server, "pilot"), join(server, "pilot")
    assert poll(ann)["state"] == "waiting"
    bob_seat = poll(bob)
    with server.services.db() as db:
        first = db.scalar(select(Trial).where(Trial.study == "pilot"))
    assert first.maze in pool
    old_page = bob.get(bob_seat["link"]).text
    assert 'data-follow="/study/pilot/seat"' in old_page and f'data-trial="{first.id}"' in old_page
    open_seats(server, first.id, "commander", "driver")  # both pages loaded: the map was seen
    eve = experimenter_client(server.services, server.url)
    assert bob.get("/study/pilot/seat").json()["trial_id"] == first.id, "the page's own trial: it stays"
    eve.post(f"/experimenter/trials/{first.id}/abort", data={"reason": "the rover fell over"})
    assert bob.get("/study/pilot/seat").json() == {"trial_id": None, "link": None}, "aborted: nothing to follow"

    eve.post(f"/experimenter/trials/{first.id}/restart")
    with server.services.db() as db:
        again = db.scalars(select(Trial).where(Trial.id > first.id)).one()
        names = dict(db.execute(select(Participant.id, Participant.name)).all())
    assert again.study == "pilot" and again.phase == "waiting" and again.excluded_reason is None
    assert again.maze in pool and again.maze != first.maze, "the pool's other layout: the first one was seen"
    assert created(server, again.id)["join_timeout_s"] == 45.0, "the study's join deadline"
    assert (names[again.commander_id], names[again.driver_id]) == (names[first.commander_id], names[first.driver_id])
    # The old seat pages ask their study where the participant sits now (static/seat.js) and go there.
    for client, code in ((ann, ann_code), (bob, bob_code)):
        seat = client.get("/study/pilot/seat").json()
        role = "commander" if names[again.commander_id] == code else "driver"
        assert seat["trial_id"] == again.id and seat["role"] == role
        verified = server.services.seats.verify(seat["link"].removeprefix("/play/"))
        assert (verified.trial_id, verified.role) == (again.id, role)
        assert browser(server.url).get(seat["link"]).status_code == 200
    assert browser(server.url).get("/study/pilot/seat").status_code == 403, "only a participant's own seat"
    assert server.services.hub.peek(again.id) is not None, "opened at once: its join deadline runs"


def test_a_restarted_practice_is_a_practice_again_and_one_whose_map_was_seen_is_not_played_twice(server):
    StudyFiles.of(server.settings.data_dir).save(template("pilot"))
    (ann, _), (bob, _) = join(server, "pilot"), join(server, "pilot")
    assert poll(ann)["state"] == "waiting" and poll(bob)["state"] == "seated"
    with server.services.db() as db:
        practice = db.scalar(select(Trial).where(Trial.study == "pilot"))
    open_seats(server, practice.id, "driver")  # the Commander's page never opened: nobody saw the map
    eve = experimenter_client(server.services, server.url)
    eve.post(f"/experimenter/trials/{practice.id}/abort")
    eve.post(f"/experimenter/trials/{practice.id}/restart")
    with server.services.db() as db:
        again = db.scalars(select(Trial).where(Trial.id > practice.id)).one()
    assert again.maze == "gen-000" and again.excluded_reason == PRACTICE_REASON, "still set aside from scores"
    assert created(server, again.id)["join_timeout_s"] == template("pilot").join_timeout_s
    assert ann.get("/study/pilot/seat").json()["trial_id"] == again.id

    open_seats(server, again.id, "commander", "driver")
    eve.post(f"/experimenter/trials/{again.id}/abort")
    refused = html.unescape(eve.post(f"/experimenter/trials/{again.id}/restart").text)
    assert "a practice is played once" in refused
    with server.services.db() as db:
        assert db.scalars(select(Trial.id).where(Trial.id > again.id)).first() is None, "nothing created"


def test_one_who_leaves_the_lobby_is_not_paired_and_a_paired_seat_counts_down_to_the_join_deadline(server):
    plan = {"practice_maze": None, "join_timeout_s": 40.0}  # lobby_presence_s stays 10 s: the test is within it
    StudyFiles.of(server.settings.data_dir).save(template("pilot").model_copy(update=plan))
    ann, _ = join(server, "pilot")
    assert poll(ann) == {"state": "waiting", "waiting": 1}
    left = ann.post("/study/pilot/lobby/leave", follow_redirects=False)
    assert left.status_code == 303 and left.headers["location"] == "/study/pilot/me"
    bob, bob_code = join(server, "pilot")
    assert poll(bob) == {"state": "waiting", "waiting": 1}, "Ann has gone: Bob is not paired with her"
    cat, cat_code = join(server, "pilot")
    cat_seat = poll(cat)
    assert cat_seat["state"] == "seated"
    with server.services.db() as db:
        names = dict(db.execute(select(Participant.id, Participant.name)).all())
        trial = db.scalar(select(Trial).where(Trial.study == "pilot"))
    assert {names[trial.commander_id], names[trial.driver_id]} == {bob_code, cat_code}

    async def seats() -> tuple[dict, dict]:
        async with SeatClient(server.ws_url, cat_seat["link"].removeprefix("/play/")) as mine:
            welcome = await mine.wait_for(lambda m: m.get("type") == "welcome")
            await asyncio.sleep(1.0)
            async with SeatClient(server.ws_url, server.services.seats.issue(trial.id, bob_role)) as _:
                started = await mine.wait_for(lambda m: m.get("type") == "status" and m["phase"] != "waiting")
        return welcome["status"], started

    bob_role = "driver" if names[trial.commander_id] == cat_code else "commander"
    waiting, started = asyncio.run(seats())
    assert waiting["phase"] == "waiting" and waiting["waiting_for"] == [bob_role]
    assert 0 < waiting["join_left_s"] <= 40.0, "the seconds left to open the seats, from the pairing"
    assert started["join_left_s"] is None, "both came: no countdown"
    assert ann.post("/study/pilot/lobby/leave").url.path == "/study/pilot/me", "leaving twice changes nothing"

"""A study's participants on every path through it, over HTTP and websockets against a real server:
a restarted trial stays in the study and their seat pages are sent on to it."""

from __future__ import annotations

import html

from sqlalchemy import select

from app.db.models import Participant, Trial
from app.study.config import StudyFiles, template
from app.study.lobby import PRACTICE_REASON
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

"""A study's participants on every path through it, over HTTP and websockets against a real server:
a restarted trial stays in the study and their seat pages are sent on to it; one who leaves the
lobby is not paired, and a paired seat counts down to its partner's join deadline; each way through
the study ends with its own completion code, given only at its end and once recorded."""

from __future__ import annotations

import asyncio
import html
import time

from sqlalchemy import select

from app.db.models import Participant, StudyEvent, Trial
from app.study.config import StudyConfig, StudyFiles, template
from app.study.lobby import PRACTICE_REASON
from bench.live import SeatClient
from tests.app.live import browser, experimenter_client, open_seats
from tests.app.test_study import hold_seat, join, poll


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


def test_one_who_leaves_the_lobby_is_not_paired_and_a_paired_seat_counts_down_to_the_join_deadline(server, trials):
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
            async with trials.of(trial.id).seat(bob_role) as _:
                started = await mine.wait_for(lambda m: m.get("type") == "status" and m["phase"] != "waiting")
        return welcome["status"], started

    bob_role = "driver" if names[trial.commander_id] == cat_code else "commander"
    waiting, started = asyncio.run(seats())
    assert waiting["phase"] == "waiting" and waiting["waiting_for"] == [bob_role]
    assert 0 < waiting["join_left_s"] <= 40.0, "the seconds left to open the seats, from the pairing"
    assert started["join_left_s"] is None, "both came: no countdown"
    assert ann.post("/study/pilot/lobby/leave").url.path == "/study/pilot/me", "leaving twice changes nothing"


CODES = {"partial": "PART-1", "no_partner": "NOPAIR-2", "withdrew": "WITHDREW-3", "screened_out": "SCREEN-4"}


def ended(server, code: str) -> list[dict]:
    """The participant's recorded ends (committed `completed` events' payloads)."""
    with server.services.db() as db:
        pid = db.scalar(select(Participant.id).where(Participant.name == code))
        return [
            e.payload
            for e in db.scalars(
                select(StudyEvent).where(StudyEvent.participant_id == pid, StudyEvent.kind == "completed")
            )
        ]


def study(name: str, **plan) -> StudyConfig:
    """The template study with `plan`'s fields, validated as a study file is."""
    return StudyConfig.model_validate({**template(name).model_dump(), **plan})


def finish(client, confirm: bool = False):
    return client.post("/study/pilot/complete", data={"confirm": "yes"} if confirm else {})


def test_i_have_finished_gives_the_plans_code_only_at_the_end_of_the_plan(server):
    plan = {"practice_maze": None, "trials_per_participant": 2, "join_timeout_s": 3.0, "outcome_codes": CODES}
    StudyFiles.of(server.settings.data_dir).save(study("pilot", **plan))
    eve = experimenter_client(server.services, server.url)
    (ann, ann_code), (bob, bob_code) = join(server, "pilot"), join(server, "pilot")

    for confirm in (False, True):  # nothing played: nothing to finish, no code, nothing recorded
        page = finish(ann, confirm)
        assert 'id="nothing-to-finish"' in page.text and "completion-code" not in page.text
    assert poll(ann)["state"] == "waiting" and poll(bob)["state"] == "seated"
    with server.services.db() as db:
        first = db.scalar(select(Trial.id).where(Trial.study == "pilot"))
    open_seats(server, first, "commander", "driver")
    page = finish(ann)  # mid-trial: the trial is under way, nothing finished yet
    assert 'id="nothing-to-finish"' in page.text and "yours is still going" in page.text
    assert "DONE-PILOT" not in finish(ann, confirm=True).text and ended(server, ann_code) == []
    eve.post(f"/experimenter/trials/{first}/abort")

    page = finish(ann)  # one of the two planned trials: asked first
    assert 'id="short-of-plan"' in page.text and "played 1 of the 2 planned trials" in page.text
    assert "completion-code" not in page.text and ended(server, ann_code) == []
    done = finish(ann, confirm=True)
    assert done.url.path == "/study/pilot/done" and 'id="completion-code">PART-1<' in done.text
    assert "DONE-PILOT" not in done.text
    assert ended(server, ann_code) == [{"study_version": 1, "outcome": "partial", "trials": 1}]
    assert 'id="completion-code">PART-1<' in finish(ann).text, "a second finish: the same end"
    assert poll(ann)["state"] == "ended" and "to-lobby" not in ann.get("/study/pilot/me").text

    cat, _ = join(server, "pilot")
    assert poll(bob)["state"] == "waiting" and poll(cat)["state"] == "seated", "Ann has ended: not paired"
    with server.services.db() as db:
        second = db.scalar(select(Trial.id).where(Trial.study == "pilot", Trial.id > first))
    open_seats(server, second, "commander", "driver")
    eve.post(f"/experimenter/trials/{second}/abort")
    done = finish(bob)  # both planned trials played: the plan's code at once
    assert done.url.path == "/study/pilot/done" and 'id="completion-code">DONE-PILOT<' in done.text
    assert ended(server, bob_code) == [{"study_version": 1, "outcome": "completed", "trials": 2}]


def test_a_partner_who_never_came_gives_the_no_partner_code_never_the_plans(server):
    StudyFiles.of(server.settings.data_dir).save(
        study("pilot", practice_maze=None, join_timeout_s=3.0, outcome_codes=CODES)
    )
    (dan, dan_code), (fay, _) = join(server, "pilot"), join(server, "pilot")
    assert poll(fay)["state"] == "waiting"
    seat = poll(dan)
    asyncio.run(hold_seat(server, seat["link"], 4.0))  # Fay never opens hers: the deadline aborts it
    page = finish(dan)
    assert 'id="short-of-plan"' in page.text and "no partner found" in page.text
    done = finish(dan, confirm=True)
    assert 'id="completion-code">NOPAIR-2<' in done.text and "DONE-PILOT" not in done.text
    assert ended(server, dan_code) == [{"study_version": 1, "outcome": "no_partner", "trials": 0}]


def test_the_lobbys_time_the_studys_time_limit_withdrawal_and_screening_out_each_end_with_their_code(server):
    files = StudyFiles.of(server.settings.data_dir)
    files.save(study("pilot", practice_maze=None, outcome_codes=CODES))
    files.save(study("quick", practice_maze=None, lobby_timeout_s=1.0, outcome_codes=CODES))
    files.save(study("late", practice_maze=None, time_limit_s=1.0, outcome_codes={"timed_out": "LATE-5"}))

    lone, lone_code = join(server, "quick")
    assert poll(lone, "quick")["state"] == "waiting"
    time.sleep(1.2)
    state = poll(lone, "quick")
    assert state["state"] == "timed_out" and state["outcome"] == "no_partner" and state["next"] == "/study/quick/done"
    assert ended(server, lone_code)[0]["outcome"] == "no_partner", "recorded before it was told"
    assert 'id="completion-code">NOPAIR-2<' in lone.get(state["next"]).text
    assert poll(lone, "quick")["state"] == "ended", "coming back: the way has ended"

    kim, kim_code = join(server, "late")
    time.sleep(1.1)  # past the study's time limit since consenting
    state = poll(kim, "late")
    assert state == {"state": "ended", "outcome": "timed_out", "next": "/study/late/done"}
    assert 'id="completion-code">LATE-5<' in kim.get(state["next"]).text

    hal, _ = join(server, "pilot")
    gone = hal.post("/study/pilot/withdraw", data={"confirm": "yes"})
    assert "You have withdrawn" in gone.text and 'id="completion-code">WITHDREW-3<' in gone.text

    (ivy, ivy_code), (joe, _) = join(server, "pilot"), join(server, "pilot")
    assert poll(ivy)["state"] == "waiting"
    eve = experimenter_client(server.services, server.url)
    page = eve.post("/experimenter/studies/pilot/screen-out", data={"code": ivy_code})
    assert f"{ivy_code} is screened out" in page.text
    assert '<td class="outcome">screened_out</td>' in page.text.split(f'data-code="{ivy_code}"')[1].split("</tr>")[0]
    again = html.unescape(eve.post("/experimenter/studies/pilot/screen-out", data={"code": ivy_code}).text)
    assert "already ended: screened_out" in again
    assert poll(joe) == {"state": "waiting", "waiting": 1}, "Ivy is out: Joe is not paired with her"
    state = poll(ivy)
    assert state["state"] == "ended" and state["outcome"] == "screened_out"
    page = ivy.get(state["next"]).text
    assert 'id="completion-code">SCREEN-4<' in page and "DONE-PILOT" not in page
    assert ended(server, ivy_code)[0]["outcome"] == "screened_out"

"""A study's paths in headless Chromium: the seat pages of a trial the experimenter aborts and
restarts move to the new trial's seats on their own; a lobby page that closes is not paired, and a
seat page counts down to its partner's join deadline."""

from __future__ import annotations

import pytest
from sqlalchemy import select

from app.db.models import Trial
from app.study.config import StudyFiles, template
from tests.app.live import experimenter_client, wait_js
from tests.e2e.test_study_in_browser import arrive, lobby_says

pytestmark = [pytest.mark.browser]


def test_the_seat_pages_follow_a_restarted_trial(browser, server):
    StudyFiles.of(server.settings.data_dir).save(template("pilot").model_copy(update={"practice_maze": None}))
    eve = experimenter_client(server.services, server.url)
    pages = [arrive(browser, server)[0] for _ in range(2)]
    for page in pages:
        page.wait_for_url("**/play/**", timeout=30_000)
        page.wait_for_selector("#status[data-phase=localizing]")  # both seats open: the trial runs
    with server.services.db() as db:
        first = db.scalar(select(Trial).where(Trial.study == "pilot"))
    assert eve.post(f"/experimenter/trials/{first.id}/abort", data={"reason": "the rover fell"}).status_code == 200
    for page in pages:
        wait_js(page, "() => !document.getElementById('after-trial').hidden")
    assert eve.post(f"/experimenter/trials/{first.id}/restart").status_code == 200
    with server.services.db() as db:
        again = db.scalars(select(Trial).where(Trial.id > first.id)).one()
    seats = server.services.seats

    def on_new_seat(url: str) -> bool:
        return "/play/" in url and seats.verify(url.rsplit("/play/", 1)[1]).trial_id == again.id

    for page in pages:
        page.wait_for_url(on_new_seat, timeout=15_000)  # each old seat page moved on its own
        page.wait_for_selector("#status[data-phase=localizing]")  # both came: the new trial runs


def test_a_closed_lobby_page_is_not_paired_and_the_seat_page_counts_down_to_the_join_deadline(browser, server):
    plan = {"practice_maze": None, "join_timeout_s": 30.0}  # lobby_presence_s stays 10 s: the test is within it
    StudyFiles.of(server.settings.data_dir).save(template("pilot").model_copy(update=plan))
    ann, _ = arrive(browser, server)
    lobby_says(ann, "only one waiting")
    ann.close(run_before_unload=True)  # her tab closes: the page tells the server as it goes
    bob, _ = arrive(browser, server)
    lobby_says(bob, "only one waiting")
    bob.wait_for_timeout(1500)
    assert "/study/pilot/lobby" in bob.url, "Bob waits alone: nobody paired him with Ann, who has gone"
    cat, _ = arrive(browser, server, opens_seats=False)  # Cat is paired with Bob but never opens her seat
    bob.wait_for_url("**/play/**", timeout=30_000)
    wait_js(bob, "() => !document.getElementById('join-countdown').hidden")
    first = float(bob.get_attribute("#join-left", "data-seconds"))
    bob.wait_for_timeout(1200)
    later = float(bob.get_attribute("#join-left", "data-seconds"))
    assert 0 < later < first <= 30.0, (first, later)
    assert "to open their page" in bob.inner_text("#join-countdown")
    cat.context.close()

"""The participant's pages say where they are (headless Chromium, a real server): the lobby names
the next step, the practice is marked as practice on the seat pages and stops at its time cap,
`/me` leads back to a live seat, trials are numbered without the practice, a questionnaire says it
is saved, withdrawing asks first and the withdrawn page repeats the code; no page of the way has a
link out of it."""

from __future__ import annotations

import pytest

from app.study.config import StudyFiles, template
from tests.app.live import experimenter_client, wait_js
from tests.e2e.pages import ARTIFACTS, page_checks
from tests.e2e.test_study_in_browser import arrive, go_on

pytestmark = [pytest.mark.browser]


def no_way_out(page) -> None:
    """Nothing on the page leads out of the study: no home link, no leaderboard."""
    outside = page.evaluate(
        """() => [...document.querySelectorAll('a[href]')].map(a => new URL(a.href, location.href))
                 .filter(u => u.origin === location.origin && !u.pathname.startsWith('/study/')
                              && !u.pathname.startsWith('/play/')).map(u => u.pathname)"""
    )
    assert outside == [], (page.url, outside)


def test_the_participants_pages_say_where_they_are(browser, server):
    plan = {"practice_time_cap_s": 6.0, "trials_per_participant": 2}
    StudyFiles.of(server.settings.data_dir).save(template("pilot").model_copy(update=plan))
    seats, eve = server.services.seats, experimenter_client(server.services, server.url)
    ann, ann_code = arrive(browser, server)
    wait_js(ann, "() => document.getElementById('next-step').textContent.includes('practice')")
    assert ann.inner_text("#next-step").startswith("Next: your practice trial (not scored, at most 0.1 minutes)")
    page_checks(ann, "study lobby, the practice next")
    ann.screenshot(path=str(ARTIFACTS / "study-lobby-next-step.png"))
    no_way_out(ann)
    bob, _ = arrive(browser, server)
    pages = (ann, bob)
    for page in pages:
        page.wait_for_url("**/play/**", timeout=30_000)
        page.wait_for_selector("#status[data-phase=localizing]")
    note = ann.inner_text("#practice-note")
    assert note == "This is a practice trial: it is not scored, and it stops when its clock reaches 0.1 minutes."
    page_checks(ann, "a practice's seat")
    no_way_out(ann)
    ann.screenshot(path=str(ARTIFACTS / "study-practice-seat.png"), full_page=True)

    # Her page for the study, opened beside the seat, leads back to the live seat.
    me = ann.context.new_page()
    me.goto(server.url + "/study/pilot/me")
    seat = seats.verify(ann.url.rsplit("/play/", 1)[1])
    assert me.is_hidden("#to-lobby"), "no way into the lobby while a trial of hers runs"
    assert seats.verify(me.get_attribute("#to-seat", "href").rsplit("/play/", 1)[1]) == seat
    page_checks(me, "study, my page, a trial live")
    me.close()

    # The practice stops at its cap (its clock runs from the start), and says so.
    for page in pages:
        page.wait_for_selector("#status[data-phase=aborted]", timeout=20_000)
        assert "the practice's 0.1 minutes are up" in page.inner_text("#status")
        go_on(page)  # nothing to rate: on to the lobby, for the study's first trial
    for page in pages:
        page.wait_for_url("**/play/**", timeout=30_000)
        page.wait_for_selector("#status[data-phase=localizing]")
    assert ann.is_hidden("#practice-note"), "a study trial is not marked as practice"
    trial_id = seats.verify(ann.url.rsplit("/play/", 1)[1]).trial_id
    assert eve.post(f"/experimenter/trials/{trial_id}/abort").status_code == 200

    # Her questionnaire says it is saved; her trials are numbered without the practice.
    go_on(ann)
    ann.wait_for_url("**/questionnaire")
    no_way_out(ann)
    ann.check("fieldset[data-question=difficulty] input[value='3']")
    ann.check("fieldset[data-question=partner] input[value='4']")
    ann.click("#send-answers")
    ann.wait_for_selector("#answers-saved")
    assert ann.inner_text("#answers-saved") == "Your answers are saved. Thank you."
    assert ann.locator("#my-trials tbody td:first-child").all_inner_texts() == ["practice", "1"]
    page_checks(ann, "study, my page, answers saved")
    ann.screenshot(path=str(ARTIFACTS / "study-me-saved.png"), full_page=True)
    no_way_out(ann)
    ann.goto(server.url + "/study/pilot/lobby")
    wait_js(ann, "() => document.getElementById('next-step').textContent.includes('trial 2 of 2')")
    ann.click("#leave")  # out of the lobby, to her page

    # Withdrawing asks first: the button alone does nothing; with the box ticked it withdraws.
    ann.wait_for_url("**/study/pilot/me")
    ann.click("#withdraw-from-study summary")
    ann.click("#withdraw")
    ann.wait_for_timeout(300)
    assert ann.url.endswith("/study/pilot/me") and ann.locator("#withdrawn").count() == 0
    ann.check("#withdraw-confirm")
    ann.click("#withdraw")
    ann.wait_for_selector("#withdrawn")
    assert ann.inner_text("#participant-code") == ann_code
    page_checks(ann, "study withdrawn")
    no_way_out(ann)
    ann.screenshot(path=str(ARTIFACTS / "study-withdrawn.png"), full_page=True)
    bob.context.close()
    ann.context.close()

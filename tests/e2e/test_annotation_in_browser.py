"""In Chromium: an annotator logs in, marks the message after which the robot was localized,
tags a phenomenon on two messages, hides the aids and submits; the log holds what was clicked."""

from __future__ import annotations

import asyncio
from concurrent.futures import ThreadPoolExecutor

import pytest

from app.annotation.events import CutMarked, Submitted, Tagged
from app.annotation.log import AnnotationLog
from app.db.models import AnnotationAssignment, Experimenter
from app.security import AccountRole, hash_password
from bench.live import SeatClient
from tests.app.live import wait_js
from tests.app.trial_play import start_trial
from tests.e2e.pages import ARTIFACTS, page_checks

pytestmark = pytest.mark.browser
SAID = [("commander", "what do you see"), ("driver", "a red wall"), ("commander", "turn left"), ("driver", "done")]


async def talk(server, seats) -> None:
    async with (
        SeatClient(server.ws_url, seats["commander"]) as commander,
        SeatClient(server.ws_url, seats["driver"]) as driver,
    ):
        seat = {"commander": commander, "driver": driver}
        await start_trial(commander, driver)
        for n, (role, text) in enumerate(SAID):
            other = driver if role == "commander" else commander
            start = len(other.received)
            await seat[role].send("chat", text=text)
            await other.event("chat", text=text, start=start)
            if n == 1:
                await commander.send("localize", x=1.2, y=1.0)
                await driver.event("phase", phase="navigating")


def test_an_annotator_marks_the_cut_and_tags_in_the_browser(browser, server, trial, seats):
    # Playwright's sync API runs a loop in this thread: the seats talk from another one.
    with ThreadPoolExecutor(1) as pool:
        pool.submit(asyncio.run, talk(server, seats)).result(timeout=60)
    with server.services.db.begin() as db:
        account = Experimenter(name="ann", password_hash=hash_password("annotate well"), role=AccountRole.ANNOTATOR)
        db.add(account)
        db.flush()
        ann = account.id
        db.add(AnnotationAssignment(trial_id=trial, annotator_id=ann))
    page = browser.new_context().new_page()
    page.goto(server.url + "/")
    page.fill("input[name=name]", "ann")
    page.fill("input[name=password]", "annotate well")
    page.click("#login")
    page.wait_for_url(server.url + "/annotate")
    assert page.inner_text("#progress") == "0 of 1 trials submitted"
    page.click(f"a[href='/annotate/trials/{trial}']")
    page.wait_for_url(f"{server.url}/annotate/trials/{trial}")
    page_checks(page, "annotate")
    numbers = page.eval_on_selector_all("#dialog li.message[data-number]", "els => els.map(e => e.dataset.number)")
    assert numbers == ["1", "2", "3", "4"]
    aid = page.locator("#dialog li.aid")
    assert aid.count() == 1 and "Commander's estimate (1.20, 1.00)" in aid.inner_text() and aid.is_visible()
    # The replay (the experimenter's replay.js on the annotator's copy of the log) draws the trace
    # and the estimate on the map, and shows the Driver's frames.
    wait_js(page, "() => document.getElementById('replay').dataset.ready === '1'")
    page.fill("#scrub", page.get_attribute("#scrub", "max"))
    page.dispatch_event("#scrub", "input")
    assert page.get_attribute("#map", "data-estimates") == "1" and int(page.get_attribute("#map", "data-poses")) > 0
    wait_js(page, "() => { const i = document.getElementById('frame'); return !i.hidden && i.naturalWidth > 0; }")
    ARTIFACTS.mkdir(exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / "annotate.png"), full_page=True)
    page.uncheck("#show-aids")
    assert not aid.is_visible() and not page.locator("#map").is_visible()
    page.check("#show-aids")
    assert aid.is_visible()

    page.check("#dialog li[data-number='2'] input[name=cut]")
    page.click("#save-cut")
    page.wait_for_selector("#dialog li.cut[data-number='2']")
    page.check("#dialog li[data-number='1'] input[name=anchor]")
    page.check("#dialog li[data-number='3'] input[name=anchor]")
    page.select_option("#tag", "communication_repair")
    page.click("#save-tag")
    page.wait_for_selector("#tags li[data-tag=communication_repair]")
    assert page.inner_text("#tags li[data-tag=communication_repair]").startswith("Communication Repair: messages 1, 3")
    assert "localized after message 2" in page.inner_text("#state")
    page.click("#submit")
    page.wait_for_url(server.url + "/annotate")
    assert page.inner_text("#progress") == "1 of 1 trials submitted"

    records = AnnotationLog(server.services.db).records(trial)
    assert [r.event for r in records] == [
        CutMarked(message=2),
        Tagged(tag="communication_repair", messages=[1, 3]),
        Submitted(),
    ]
    assert {r.annotator_id for r in records} == {ann}

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
from tests.app.live import TrialHandle, experimenter_client, wait_js
from tests.app.trial_play import claim_and_decide, drive_to_target, start_trial
from tests.e2e.pages import ARTIFACTS, experimenter, log_in, page_checks

pytestmark = pytest.mark.browser
SAID = [("commander", "what do you see"), ("driver", "a red wall"), ("commander", "turn left"), ("driver", "done")]


async def talk(server, trial: TrialHandle, finish: bool = False) -> None:
    """`trial`'s dialog `SAID`, the estimate after message 2; with `finish`, the three targets reached."""
    async with (
        trial.seat("commander") as commander,
        trial.seat("driver") as driver,
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
        if finish:  # only finished trials are annotated for agreement, exported and reported
            for _ in range(3):
                await drive_to_target(server.services, trial.id, driver)
                await claim_and_decide(commander, driver, confirm=True)
            await commander.event("phase", phase="finished")


def test_an_annotator_marks_the_cut_and_tags_in_the_browser(browser, server, trial):
    # Playwright's sync API runs a loop in this thread: the seats talk from another one.
    with ThreadPoolExecutor(1) as pool:
        pool.submit(asyncio.run, talk(server, trial)).result(timeout=60)
    with server.services.db.begin() as db:
        account = Experimenter(name="ann", password_hash=hash_password("annotate well"), role=AccountRole.ANNOTATOR)
        db.add(account)
        db.flush()
        ann = account.id
        db.add(AnnotationAssignment(trial_id=trial.id, annotator_id=ann))
    page = log_in(browser, server, "ann", "annotate well", "/annotate")
    assert page.inner_text("#progress") == "0 of 1 trials submitted"
    page.click(f"a[href='/annotate/trials/{trial.id}']")
    page.wait_for_url(f"{server.url}/annotate/trials/{trial.id}")
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

    records = AnnotationLog(server.services.db).records(trial.id)
    assert [r.event for r in records] == [
        CutMarked(message=2),
        Tagged(tag="communication_repair", messages=[1, 3]),
        Submitted(),
    ]
    assert {r.annotator_id for r in records} == {ann}


def annotate(page, server, trial: int, cut: int, tags: dict[str, list[int]]) -> None:
    """One annotator's whole trial in the page: the cut, each tag on its messages, submit."""
    page.goto(f"{server.url}/annotate/trials/{trial}")
    page.check(f"#dialog li[data-number='{cut}'] input[name=cut]")
    page.click("#save-cut")
    page.wait_for_selector(f"#dialog li.cut[data-number='{cut}']")
    for tag, anchors in tags.items():
        for n in anchors:
            page.check(f"#dialog li[data-number='{n}'] input[name=anchor]")
        page.select_option("#tag", tag)
        page.click("#save-tag")
        page.wait_for_selector(f"#tags li[data-tag={tag}]")
    page.click("#submit")
    page.wait_for_url(server.url + "/annotate")


@pytest.mark.slow
def test_two_annotators_agree_as_worked_by_hand_and_the_ldh_instance_takes_the_adjudicated_cut(browser, server, trials):
    from app.db.models import Trial
    from app.export.ndh import ldh_instances
    from app.export.source import load_trial

    services = server.services
    names = services.mazes.names()
    played = [trials.new(maze=names[i], team=team) for i, team in enumerate(("Owls", "Larks", "Wrens"))]
    with ThreadPoolExecutor(1) as pool:
        for trial in played:
            pool.submit(asyncio.run, talk(server, trial, finish=True)).result(timeout=180)
    trial_ids = [trial.id for trial in played]
    with services.db.begin() as db:
        ids = {}
        for name in ("ann", "bob"):
            account = Experimenter(name=name, password_hash=hash_password("annotate well"), role=AccountRole.ANNOTATOR)
            db.add(account)
            db.flush()
            ids[name] = account.id
        for t in trial_ids:
            db.get(Trial, t).study = "s25"
            db.add(AnnotationAssignment(trial_id=t, annotator_id=ids["ann"]))
        for t in trial_ids[:2]:  # two trials for both, the third once
            db.add(AnnotationAssignment(trial_id=t, annotator_id=ids["bob"]))
    pages = {}
    for name in ("ann", "bob"):
        pages[name] = log_in(browser, server, name, "annotate well", "/annotate")
    t1, t2, t3 = trial_ids
    annotate(pages["ann"], server, t1, 2, {"needs_history": [1]})
    annotate(pages["bob"], server, t1, 2, {"needs_history": [2]})
    annotate(pages["ann"], server, t2, 2, {})
    annotate(pages["bob"], server, t2, 4, {"needs_history": [1]})
    annotate(pages["ann"], server, t3, 1, {"surrender_control": [4]})
    assert pages["ann"].inner_text("#progress") == "3 of 3 trials submitted"
    assert pages["bob"].inner_text("#progress") == "2 of 2 trials submitted"

    # By hand, over the two trials both annotated: needs_history ann yes/no, bob yes/yes: p_o 0.5,
    # p_e 0.5 * 1 + 0.5 * 0 = 0.5, kappa 0; the cuts 2/2 and 2/4: distances 0 and 2, mean 1.
    experimenter_client(services, server.url).close()  # the account `experimenter` logs in with
    eve = experimenter(browser, server)
    eve.goto(f"{server.url}/experimenter/annotation?study=s25")
    assert eve.inner_text("#double") == "2 trials annotated by two annotators."
    assert eve.inner_text("#kappa tr[data-tag=needs_history] .k") == "0.000"
    assert "mean distance 1.00 messages, the same cut in 50 % of trials" in eve.inner_text("#cut-distance")
    row = eve.locator(f"#disagreements tr[data-trial='{t2}'][data-item=cut]")
    assert "ann: 2; bob: 4" in row.inner_text()
    row.locator("input[name=value]").fill("3")
    row.locator("button").click()
    eve.wait_for_selector(f"#disagreements tr[data-trial='{t2}'][data-item=cut] .adjudicated:text('3')")

    with services.db() as db:
        record = load_trial(db, services.settings, t2)
    (instance,) = ldh_instances(record, services.mazes.load(record.maze))
    assert instance["localization_source"] == "adjudicated" and instance["localized_after_message"] == 3


async def long_talk(trial: TrialHandle, n: int) -> None:
    """`n` messages, `trial`'s two seats in turn."""
    async with (
        trial.seat("commander") as commander,
        trial.seat("driver") as driver,
    ):
        await start_trial(commander, driver)
        for k in range(n):
            said, other = (commander, driver) if k % 2 == 0 else (driver, commander)
            start = len(other.received)
            await said.send("chat", text=f"message {k + 1}")
            await other.event("chat", text=f"message {k + 1}", start=start)


@pytest.mark.settings(seat_message_burst=100)  # 60 messages at once, not a person's pace
def test_the_controls_stay_in_view_along_a_long_dialog(browser, server, trial):
    with ThreadPoolExecutor(1) as pool:
        pool.submit(asyncio.run, long_talk(trial, 60)).result(timeout=60)
    with server.services.db.begin() as db:
        account = Experimenter(name="ann", password_hash=hash_password("annotate well"), role=AccountRole.ANNOTATOR)
        db.add(account)
        db.flush()
        db.add(AnnotationAssignment(trial_id=trial.id, annotator_id=account.id))
    page = log_in(browser, server, "ann", "annotate well", "/annotate", viewport={"width": 1280, "height": 800})
    page.goto(f"{server.url}/annotate/trials/{trial.id}")
    in_view = """(sel) => { const r = document.querySelector(sel).getBoundingClientRect();
                            return r.top >= -1 && r.bottom <= innerHeight + 1; }"""
    for n in (1, 30):  # the dialog's start, and its middle scrolled to the top of the window
        page.eval_on_selector(f"#dialog li[data-number='{n}']", "e => e.scrollIntoView({block: 'start'})")
        assert page.evaluate(in_view, f"#dialog li[data-number='{n}']")
        for control in ("#save-cut", "#tag", "#save-tag", "#submit"):
            assert page.evaluate(in_view, control), f"{control} is out of view at message {n}"
    page.screenshot(path=str(ARTIFACTS / "annotate-long-dialog.png"))
    page.check("#dialog li[data-number='30'] input[name=cut]")
    page.click("#save-cut")
    page.wait_for_selector("#dialog li.cut[data-number='30']")

"""Alerts in headless Chromium: paired in the lobby, the waiting page's title changes, it beeps (the
participant clicked "Sound on" first, as browsers require) and it names both seats before the seat
opens; a claim does the same on the Commander's page, which calms once it is judged."""

from __future__ import annotations

import pytest

from app.study.config import StudyFiles, template
from tests.app.live import wait_js
from tests.e2e.test_study_in_browser import arrive, lobby_says

pytestmark = [pytest.mark.browser, pytest.mark.slow]


def test_pairing_and_a_claim_raise_the_title_a_beep_and_the_seats(browser, server):
    StudyFiles(server.settings.data_dir / "studies").save(template("pilot").model_copy(update={"practice_maze": None}))
    ann, _ = arrive(browser, server)
    lobby_says(ann, "only one waiting")
    ann.click("#sound-on")
    ann.wait_for_selector("#sound-on >> text=Sound is on")
    assert ann.title().endswith("lobby"), "the sound test raises nothing"
    bob, _ = arrive(browser, server)

    ann.wait_for_selector("body[data-alert='Paired!']")
    assert ann.title().startswith("Paired! · ")
    assert ann.evaluate("document.body.dataset.beeped") == "true", "clicked first: it sounded"
    role = ann.get_attribute("#lobby", "data-seat")
    partner = ann.get_attribute("#lobby", "data-partner-seat")
    assert {role, partner} == {"commander", "driver"}
    assert f"your partner is the {partner.capitalize()}" in ann.inner_text("#lobby-status")
    assert bob.evaluate("document.body.dataset.beeped") in ("false", None), "no click on Bob's page: silent"

    for page in (ann, bob):
        page.wait_for_url("**/play/**", timeout=30_000)
    seats = {server.services.seats.verify(p.url.rsplit("/play/", 1)[1]).role: p for p in (ann, bob)}
    commander, driver = seats["commander"], seats["driver"]
    commander.wait_for_selector("#status[data-phase=localizing]")
    commander.click("#map")  # "the robot is here": a click, so the page may sound from now on
    driver.wait_for_selector("#status[data-phase=navigating]")
    assert commander.evaluate("document.body.dataset.alert") is None
    driver.click("#found")
    commander.wait_for_selector("body[data-alert='Claim to judge']")
    assert commander.title().startswith("Claim to judge · ")
    assert commander.evaluate("document.body.dataset.beeped") == "true"
    commander.click("#claim:not([hidden]) #reject")
    wait_js(commander, "() => !document.body.dataset.alert && !document.title.startsWith('Claim')")

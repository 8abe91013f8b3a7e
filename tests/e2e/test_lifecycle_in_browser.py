"""The dashboard's delete buttons in headless Chromium: an unused participant goes; a team
member stays, and the page says why."""

from __future__ import annotations

import pytest

from app.db.models import Experimenter
from app.security import hash_password
from bench.live import REPO

ARTIFACTS = REPO / "test-artifacts"

pytestmark = pytest.mark.browser


def test_delete_buttons_remove_what_nothing_uses_and_say_why_not(browser, server):
    with server.services.db.begin() as db:
        db.add(Experimenter(name="eve", password_hash=hash_password("correct horse")))
    page = browser.new_context(viewport={"width": 1280, "height": 900}).new_page()
    page.goto(server.url + "/")
    page.fill("input[name=name]", "eve")
    page.fill("input[name=password]", "correct horse")
    page.click("#login")
    for name in ("Ada", "Ben", "Cy"):
        page.fill("input[aria-label='Participant name']", name)
        page.click("#add-participant")
    page.fill("input[aria-label='Team name']", "Pair")
    page.click("#add-team")  # Ada and Ben
    page.click("button[aria-label='Delete participant Ada']")
    page.wait_for_selector("#error >> text=participant 'Ada' is a member of team 'Pair': delete the team first")
    ARTIFACTS.mkdir(exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / "dashboard-delete-refused.png"))
    page.click("button[aria-label='Delete participant Cy']")
    page.wait_for_selector("#participants li >> text=Cy", state="detached")
    assert page.locator("#participants li").all_inner_texts() == ["Ada delete", "Ben delete"]
    page.click("button[aria-label='Delete team Pair']")
    page.wait_for_selector("#teams li >> text=Pair", state="detached")
    page.context.close()

"""A panel's study link in headless Chromium: the address bar is clean once the page has loaded
(the identifiers stored with the pseudonym), the participant's pages show none of them, and the
end page takes the browser on to the panel's completion address with the outcome's code."""

from __future__ import annotations

import pytest

from app.study.config import StudyFiles
from tests.app.test_study_panel import PROLIFIC, stored
from tests.app.test_study_paths import CODES, study
from tests.e2e.pages import page_checks

pytestmark = [pytest.mark.browser, pytest.mark.slow]


def test_a_panel_link_leaves_a_clean_address_bar_and_the_end_lands_on_the_panel(browser, server):
    StudyFiles.of(server.settings.data_dir).save(
        study("pilot", practice_maze=None, outcome_codes=CODES, panel={"completion_url": PROLIFIC})
    )
    context = browser.new_context()
    landed: list[str] = []

    def panel(route) -> None:  # the panel's site, here: what the browser asked of it
        landed.append(route.request.url)
        route.fulfill(status=200, content_type="text/html", body="<title>Prolific</title><p>submitted</p>")

    context.route("https://app.prolific.com/**", panel)
    page = context.new_page()
    page.goto(f"{server.url}/study/pilot?PROLIFIC_PID=PID-ZOE&STUDY_ID=ST-77&SESSION_ID=SE-9")
    assert page.url == f"{server.url}/study/pilot", "the identifiers are gone from the address bar"
    assert page.evaluate("history.length") == 2 and "PID-ZOE" not in page.content()
    page.click("#agree")
    code = page.inner_text("#participant-code")
    assert stored(server, code).panel_participant == "PID-ZOE"
    page.click("#continue")
    page.click("#to-lobby")
    page.wait_for_url("**/study/pilot/lobby")
    page.click("#leave")
    page.wait_for_url("**/study/pilot/me")
    assert "PID-ZOE" not in page.content() and "SE-9" not in page.content()
    page.click("summary")
    page.check("#withdraw-confirm")
    page.click("#withdraw")
    page.wait_for_selector("#withdrawn")
    page_checks(page, "withdrawn, on to the panel")  # axe: a countdown that can be stopped
    assert page.get_attribute("#completion-link", "href") == PROLIFIC.format(code="WITHDREW-3")
    page.wait_for_url("https://app.prolific.com/**", timeout=30_000)  # after the 10 s countdown
    assert landed == [PROLIFIC.format(code="WITHDREW-3")]

    # One who stops the countdown stays, and goes on by the link when ready.
    page.goto(f"{server.url}/study/pilot?PROLIFIC_PID=PID-YAN&STUDY_ID=ST-77&SESSION_ID=SE-8")
    page.click("#agree")
    page.click("#continue")
    page.goto(f"{server.url}/study/pilot/me")
    page.click("summary")
    page.check("#withdraw-confirm")
    page.click("#withdraw")
    page.click("#stay")
    page.wait_for_timeout(11_000)
    assert page.url.startswith(server.url) and "You stay here" in page.inner_text("#onward")
    page.click("#completion-link")
    page.wait_for_url("https://app.prolific.com/**")
    assert len(landed) == 2
    context.close()

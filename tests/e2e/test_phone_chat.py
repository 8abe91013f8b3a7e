"""On a 390 px wide phone both seats keep the chat's newest messages and its input on screen
while the participant drives or looks at the map (headless Chromium, a real server)."""

from __future__ import annotations

import pytest

from bench.live import REPO
from tests.app.live import wait_js

ARTIFACTS = REPO / "test-artifacts"
PHONE = {"viewport": {"width": 390, "height": 844}, "has_touch": True, "is_mobile": True}

pytestmark = pytest.mark.browser


def on_screen(page, selector: str) -> bool:
    """The element's whole box lies inside the viewport."""
    return page.evaluate(
        """(sel) => { const r = document.querySelector(sel).getBoundingClientRect();
                     return r.height > 0 && r.top >= 0 && r.bottom <= innerHeight && r.left >= 0 && r.right <= innerWidth; }""",
        selector,
    )


@pytest.mark.settings(min_move_interval_s=0.0)
def test_the_newest_messages_and_the_input_stay_on_a_phone_screen(browser, server, trial):
    pages = {}
    for role in ("commander", "driver"):
        page = browser.new_context(**PHONE).new_page()
        page.goto(trial.play_url(role))
        pages[role] = page
    for page in pages.values():
        page.wait_for_selector("#status[data-phase=localizing]")
    for k in range(6):
        role = ("commander", "driver")[k % 2]
        pages[role].fill("#chat-input", f"message {k} from the {role}")
        pages[role].press("#chat-input", "Enter")
    ARTIFACTS.mkdir(exist_ok=True)
    for role, page in pages.items():
        page.wait_for_selector("#messages li:nth-child(6)")
        work = "#map" if role == "commander" else "#found"  # looking at the map; driving
        for where in ("top", "work", "bottom"):
            page.evaluate(
                {
                    "top": "scrollTo(0, 0)",
                    "work": f"document.querySelector('{work}').scrollIntoView({{block: 'start'}})",
                    "bottom": "scrollTo(0, document.body.scrollHeight)",
                }[where]
            )
            page.screenshot(path=str(ARTIFACTS / f"phone-{role}-{where}.png"))
            assert on_screen(page, "#chat-input"), f"{role}: the input is off screen ({where})"
            assert on_screen(page, "#messages li:last-child"), f"{role}: the newest message is off screen ({where})"
        # Scrolled to the map or the buttons, they are above the chat, not under it.
        page.evaluate(f"document.querySelector('{work}').scrollIntoView({{block: 'start'}})")
        hidden = page.evaluate(
            f"""() => {{ const a = document.querySelector('{work}').getBoundingClientRect(),
                              c = document.querySelector('.chat').getBoundingClientRect();
                        return a.top < c.top ? 0 : 1; }}"""
        )
        assert hidden == 0, f"{role}: the chat covers {work}"
        assert page.evaluate("document.documentElement.scrollWidth") <= 390, "nothing scrolls sideways"
    for page in pages.values():
        page.context.close()


def below_the_chat(page, selector: str) -> bool:
    """Some of the element lies under the docked chat."""
    return page.evaluate(
        """(sel) => document.querySelector(sel).getBoundingClientRect().bottom
                    > document.querySelector('.chat').getBoundingClientRect().top""",
        selector,
    )


@pytest.mark.settings(min_move_interval_s=0.0)
def test_on_a_phone_the_target_photo_and_a_claim_are_above_the_chat_and_the_moves_read_left_to_right(
    browser, server, trial
):
    commander, driver = (browser.new_context(**PHONE).new_page() for _ in range(2))
    commander.goto(trial.play_url("commander"))
    driver.goto(trial.play_url("driver"))
    driver.wait_for_selector("#status[data-phase=localizing]")
    commander.tap("#map")
    driver.wait_for_selector("#status[data-phase=navigating]")
    commander.wait_for_selector("#target-image:not([hidden])")
    commander.evaluate("scrollTo(0, 0)")
    commander.wait_for_timeout(100)
    assert on_screen(commander, "#target-image") and not below_the_chat(commander, "#target-image")
    assert not below_the_chat(commander, "#map"), "the map and the target's photo are seen together"
    commander.screenshot(path=str(ARTIFACTS / "phone-commander-target.png"))

    # Left, forward and right side by side in that order, as the arrow keys; the claim below them.
    boxes = {b: driver.locator(f"#{b}").bounding_box() for b in ("left", "forward", "right", "found")}
    assert boxes["left"]["y"] == boxes["forward"]["y"] == boxes["right"]["y"] < boxes["found"]["y"]
    assert boxes["left"]["x"] < boxes["forward"]["x"] < boxes["right"]["x"]
    driver.screenshot(path=str(ARTIFACTS / "phone-driver-buttons.png"))

    # A claim: the Commander's Confirm takes the focus, in view above the chat.
    commander.evaluate("scrollTo(0, document.body.scrollHeight)")
    driver.click("#found")
    commander.wait_for_selector("#claim:not([hidden])")
    wait_js(commander, "document.activeElement && document.activeElement.id === 'confirm'")
    assert on_screen(commander, "#confirm") and not below_the_chat(commander, "#confirm")
    for page in (commander, driver):
        page.context.close()

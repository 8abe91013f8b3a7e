"""On a 390 px wide phone both seats keep the chat's newest messages and its input on screen
while the participant drives or looks at the map (headless Chromium, a real server)."""

from __future__ import annotations

import pytest

from bench.live import REPO

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
    services = server.services
    pages = {}
    for role in ("commander", "driver"):
        page = browser.new_context(**PHONE).new_page()
        page.goto(f"{server.url}/play/{services.seats.issue(trial, role)}")
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

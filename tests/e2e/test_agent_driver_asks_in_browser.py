"""End to end in headless Chromium: a person-like script on the Commander's page tells the agent
Driver to turn around in words no reader was trained on. The Driver does not guess: it holds still
and asks; the script says it plainly, and the Driver turns around."""

from __future__ import annotations

import math

import pytest

from tests.app.live import add_experimenter
from tests.e2e.pages import ARTIFACTS, mark_on_map, trial_with_an_agent
from tests.e2e.test_agent_driver_in_browser import held_still, say

MAZE = "gen-000"
# A turn-around as a person might put it, in words no training turn and no rule has.
UNHEARD = "pirouette till the wall you were staring at sits behind your tail"

pytestmark = pytest.mark.browser


def _heading(backend) -> float:
    return backend.pose()[2]


@pytest.mark.slow
def test_told_in_words_it_never_met_it_asks_and_then_does_it(browser, start_server):
    ARTIFACTS.mkdir(exist_ok=True)
    server = start_server(min_move_interval_s=0.1)
    services = server.services
    add_experimenter(server)
    admin, trial_id = trial_with_an_agent(browser, server, MAZE, "driver")
    page = browser.new_context(viewport={"width": 1280, "height": 860}).new_page()
    page.goto(admin.get_attribute("a.join-commander", "href"))
    page.wait_for_selector("#status[data-phase=localizing]")
    mark_on_map(page)
    page.wait_for_selector("#status[data-phase=navigating]")
    runtime = services.hub.peek(trial_id)
    backend = runtime.robot.backend
    start = _heading(backend)

    asked = say(page, UNHEARD)
    assert asked.endswith("?") and UNHEARD in asked, asked  # it says which words it did not get
    assert held_still(runtime, 1.0), "it acted on words it did not understand"

    done = say(page, "turn around")  # its answer comes once the turn is done
    page.screenshot(path=str(ARTIFACTS / "agent-driver-asks.png"), full_page=True)
    turned = abs(math.remainder(_heading(backend) - start, 2 * math.pi))
    assert turned == pytest.approx(math.pi, abs=0.1), (asked, done)

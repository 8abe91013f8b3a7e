"""End to end in headless Chromium: the experimenter sets up a trial through the pages, one
browser context is the Commander and another the Driver; they chat, the Commander marks the
robot, the Driver drives (the shortest path chooses the keys) to the three targets, each
confirmed, and the team appears on the leaderboard. Screenshots go to test-artifacts/."""

from __future__ import annotations

import base64
import re

import pytest

from sim.core.labels import Label
from tests.app.live import add_experimenter, wait_js
from tests.app.trial_play import object_pixels
from tests.e2e.pages import ARTIFACTS, drive_page_to_target, experimenter, team_of_two

pytestmark = pytest.mark.browser


def socket_log(page) -> list[str]:
    """Every websocket message the page receives."""
    received: list[str] = []
    page.on("websocket", lambda ws: ws.on("framereceived", lambda payload: received.append(str(payload))))
    return received


@pytest.mark.slow
@pytest.mark.settings(min_move_interval_s=0.0)
def test_two_browsers_complete_a_trial_to_the_leaderboard(browser, server):
    ARTIFACTS.mkdir(exist_ok=True)
    services = server.services
    add_experimenter(server)
    # The experimenter registers two participants, forms a team and creates a trial.
    admin = experimenter(browser, server, viewport={"width": 1400, "height": 900})
    team_of_two(admin)
    admin.fill("input[aria-label='Targets']", "mug, paddle, jar")
    admin.click("#create-trial")
    commander_url = admin.get_attribute("a.join-commander", "href")
    driver_url = admin.get_attribute("a.join-driver", "href")
    trial_id = int(admin.get_attribute("tr[data-trial]", "data-trial"))

    cctx = browser.new_context(viewport={"width": 1280, "height": 860})
    dctx = browser.new_context(viewport={"width": 1280, "height": 860})
    commander, driver = cctx.new_page(), dctx.new_page()
    commander_heard, driver_heard = socket_log(commander), socket_log(driver)
    driver_requests: list[str] = []
    driver.on("request", lambda r: driver_requests.append(r.url))
    commander.goto(commander_url)
    driver.goto(driver_url)
    commander.wait_for_selector("#status[data-phase=localizing]")
    driver.wait_for_selector("#status[data-phase=localizing]")
    wait_js(driver, "document.getElementById('camera').src.startsWith('data:image/jpeg')")

    commander.fill("#chat-input", "Hi! What colours do you see?")
    commander.press("#chat-input", "Enter")
    driver.wait_for_selector("#messages li.commander >> text=What colours do you see?")
    driver.fill("#chat-input", "A blue wall on my left and yellow ahead.")
    driver.click(".chat button")
    commander.wait_for_selector("#messages li.driver >> text=yellow ahead")

    # "The robot is here": a click with a drag for the heading ends localization.
    box = commander.locator("#map").bounding_box()
    commander.mouse.move(box["x"] + box["width"] * 0.4, box["y"] + box["height"] * 0.5)
    commander.mouse.down()
    commander.mouse.move(box["x"] + box["width"] * 0.45, box["y"] + box["height"] * 0.5)
    commander.mouse.up()
    driver.wait_for_selector("#status[data-phase=navigating]")
    runtime = services.hub.peek(trial_id)
    assert runtime.state.localization.heading == pytest.approx(0.0, abs=0.05)

    # The experimenter's dashboard shows the running trial with its true pose.
    admin.goto(server.url + "/experimenter")
    live = admin.locator(f'figure.live-trial[data-trial="{trial_id}"] figcaption')
    live.filter(has_text="navigating").wait_for()
    assert "commander ●" in live.inner_text() and "driver ●" in live.inner_text()

    def screenshots(n: int) -> None:
        if n == 6:
            driver.screenshot(path=str(ARTIFACTS / "driver.png"))
            admin.wait_for_timeout(1100)  # one dashboard refresh
            admin.screenshot(path=str(ARTIFACTS / "experimenter.png"))

    for index in range(3):
        drive_page_to_target(services, trial_id, driver, on_move=screenshots if index == 0 else None)
        driver.click("#found")
        commander.wait_for_selector("#claim:not([hidden])")
        wait_js(commander, "document.getElementById('claim-image').src.startsWith('data:image/jpeg')")
        # The landmark is a physical object: the claimed frame shows it, not the wall behind it.
        claimed = commander.get_attribute("#claim-image", "src").split(",", 1)[1]
        target = runtime.state.current_target
        assert object_pixels(base64.b64decode(claimed), Label[target.upper()]) > 300, target
        if index == 0:
            commander.screenshot(path=str(ARTIFACTS / "commander.png"))
            # While the claim waits, the Driver cannot move or claim again, and every page says so.
            driver.wait_for_selector("#forward:disabled")
            assert driver.is_disabled("#found") and driver.is_disabled("#left")
            driver.wait_for_selector("#status >> text=Waiting for the Commander to confirm your claim.")
            driver.screenshot(path=str(ARTIFACTS / "driver-claim.png"))
            admin.goto(f"{server.url}/experimenter/trials/{trial_id}")
            admin.wait_for_selector("#status >> text=The Driver claims target 1 of 3")
            assert admin.is_hidden("#ldh-note"), "no LDH caption without its discs"
            # The experimenter's page follows the dialog: the chat, the next target, the pending claim.
            admin.wait_for_selector(f"#claim-note >> text=Claim pending: the Driver says target 1 ({target})")
            assert admin.inner_text("#next-target") == target and admin.locator("#messages li").count() >= 1
            admin.screenshot(path=str(ARTIFACTS / "watch-claim.png"))
        commander.click("#confirm")
        if index == 0:
            driver.wait_for_selector("#forward:enabled")
            assert driver.inner_text("#error") == ""
            # The verdict is a line of both seats' chat, in the dialog's order.
            for page in (commander, driver):
                page.wait_for_selector(f"#messages li.note >> text=Confirmed: the {target} is found.")
            # ... and of the experimenter's, with the ground truth (it had been a note at the top alone).
            admin.wait_for_selector(f"#messages li.note >> text=Confirmed: target 1 ({target}) (truly within reach")
        commander.wait_for_selector("#claim[hidden]", state="attached")
    commander.wait_for_selector("#status[data-phase=finished]")
    driver.wait_for_selector("#status[data-phase=finished]")
    commander.screenshot(path=str(ARTIFACTS / "commander-finished.png"))
    admin.wait_for_selector("#score-box:not([hidden])")
    assert float(admin.inner_text("#score").removesuffix(" s")) > 0  # the leaderboard's score, on the trial's page
    admin.screenshot(path=str(ARTIFACTS / "watch-finished.png"))
    driver.screenshot(path=str(ARTIFACTS / "driver-finished.png"))

    board = browser.new_context().new_page()
    board.goto(server.url + "/leaderboard")
    row = board.locator("#leaderboard tbody tr").first
    assert row.locator(".team").inner_text() == "Ada & Ben"
    board.screenshot(path=str(ARTIFACTS / "leaderboard.png"))

    # What each browser was sent: no camera frame to the Commander, no map to the Driver.
    assert commander_heard and driver_heard
    assert not any('"kind":"frame"' in m or '"kind":"pose"' in m for m in commander_heard)
    assert any('"kind":"frame"' in m for m in driver_heard)
    assert not any('"kind":"localization"' in m for m in driver_heard)
    assert not any(re.search(r"map\.png|/target/", url) for url in driver_requests)

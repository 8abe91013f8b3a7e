"""The experimenter's robots in headless Chromium: a robot registered through the dashboard's
form shows its token once; a trial on it waits for it (the dashboard and the seats say so);
the real `robotslang-robot` process connects with the token, the trial starts, and the
dashboard follows the link live (connected, frames per second, latency), and when it goes."""

from __future__ import annotations

import pytest

from app.db.models import Experimenter
from app.security import hash_password
from tests.app.live import wait_js
from tests.app.robot_rig import ROBOT_START_S, RobotProcess
from tests.e2e.pages import ARTIFACTS, experimenter

pytestmark = pytest.mark.browser


def test_a_robot_registered_on_the_dashboard_connects_with_its_token_and_shows_live(browser, server, tmp_path):  # noqa: F811
    ARTIFACTS.mkdir(exist_ok=True)
    robot = None
    try:
        with server.services.db.begin() as db:
            db.add(Experimenter(name="eve", password_hash=hash_password("correct horse")))
        # Logged in and the dashboard loaded, its scripts with it: a form submitted before its
        # script took it over was posted by the browser itself, and no token was shown (CI, loaded).
        page = experimenter(browser, server, viewport={"width": 1400, "height": 1000})
        page.fill("input[aria-label='Robot name']", "rover A")
        page.click("#add-robot")
        page.wait_for_selector("#robot-token:not([hidden]) .token:not(:empty)")
        token = page.inner_text("#robot-token .token")
        assert f"--token {token}" in page.inner_text("#robot-token .command")
        row = page.locator("#robots tr[data-robot]", has_text="rover A")
        row.locator(".link", has_text="not connected").wait_for()
        page.fill("input[aria-label='Robot name']", "rover A")
        page.click("#add-robot")
        page.locator("#robot-error", has_text="robot 'rover A' already exists").wait_for()
        assert page.is_hidden("#robot-token")

        # A trial on the rover, joined by both participants, waits for the rover, and says so.
        robot_id = row.get_attribute("data-robot")
        for name in ("Ada", "Ben"):
            page.fill("input[aria-label='Participant name']", name)
            page.click("#add-participant")
        page.fill("input[aria-label='Team name']", "Ada & Ben")
        page.click("#add-team")
        page.select_option("#backend", f"robot:{robot_id}")
        page.click("#create-trial")
        trial = page.locator("#trials tr[data-trial]")
        assert trial.locator("td", has_text="rover A (rover)").count() == 1
        seats = [browser.new_context().new_page() for _ in range(2)]
        for seat, role in zip(seats, ("commander", "driver")):
            seat.goto(page.get_attribute(f"a.join-{role}", "href"))
        seats[1].locator("#status", has_text="waiting for the robot").wait_for()
        trial.locator(".phase", has_text="waiting for robot").wait_for()
        assert seats[1].is_disabled("#forward"), "no move is offered before the robot is there"

        robot = RobotProcess(tmp_path, server.url, token)
        seats[1].wait_for_selector("#status[data-phase=localizing]", timeout=ROBOT_START_S * 1000)
        trial.locator(".phase", has_text="localizing").wait_for()
        wait_js(
            page,
            "() => { const r = [...document.querySelectorAll('#robots tr[data-robot]')]"
            ".find((tr) => tr.querySelector('.name').textContent === 'rover A');"
            " return r && r.querySelector('.link').textContent === 'connected'"
            " && parseFloat(r.querySelector('.fps').textContent) > 5; }",
            timeout_s=ROBOT_START_S,
        )
        assert row.locator(".latency").inner_text().endswith(" ms")
        option = page.locator("#backend option", has_text="rover A")
        assert option.inner_text() == "rover A (rover, connected)"
        page.screenshot(path=str(ARTIFACTS / "experimenter-robots.png"))

        page.reload()  # the token was shown once: the page never holds it again
        assert token not in page.content()
        robot.stop()
        row.locator(".link", has_text="not connected").wait_for(timeout=ROBOT_START_S * 1000)
        assert page.locator("#backend option", has_text="rover A").inner_text() == "rover A (rover, not connected)"
    finally:
        if robot is not None:
            robot.stop()

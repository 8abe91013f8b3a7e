"""The pages a new user meets, in headless Chromium against a real server on loopback: the
Commander's map with its landmarks, the participants' clock, moves and plain status through a
pause and an abort, localization by keyboard and by touch, a seat taken over and back, the
agent leaderboard (every page's axe-core check and phone width: test_accessibility.py)."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from app.db.models import Experimenter, Team, Trial
from app.security import hash_password
from sim.core.labels import LABEL_BGR, OBJECT_LABELS
from tests.app.live import wait_js
from tests.e2e.pages import ARTIFACTS, H_M, W_M, experimenter, still_box, wait_until

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def server(start_module_server):
    running = start_module_server(min_move_interval_s=0.0)
    with running.services.db.begin() as db:
        db.add(Experimenter(name="eve", password_hash=hash_password("correct horse")))
    return running


_teams = iter(range(1000))


def new_trial(trials, **kw) -> tuple[int, str, str]:
    """A trial of a team of its own (the module's server keeps every test's): its id and join links."""
    trial = trials.new(team=f"Team {next(_teams)}", **kw)
    return trial.id, trial.play_url("commander"), trial.play_url("driver")


def seat_pages(browser, commander_url: str, driver_url: str):
    commander = browser.new_context(viewport={"width": 1280, "height": 900}).new_page()
    driver = browser.new_context(viewport={"width": 1280, "height": 900}).new_page()
    commander.goto(commander_url)
    driver.goto(driver_url)
    for page in (commander, driver):
        page.wait_for_selector("#status[data-phase=localizing]")
    return commander, driver


def click_map(page, fx: float, fy: float) -> None:
    box = page.locator("#map").bounding_box()
    page.mouse.click(box["x"] + box["width"] * fx, box["y"] + box["height"] * fy)


def test_commander_map_shows_the_landmarks_and_no_driver_request_gets_it(browser, server, trials):
    trial_id, commander_url, driver_url = new_trial(trials, targets=("mug", "jar", "paddle"))
    driver_requests: list[str] = []
    commander, driver = seat_pages(browser, commander_url, driver_url)
    driver.on("request", lambda r: driver_requests.append(r.url))

    png = commander.request.get(commander_url + "/map.png")
    assert png.ok
    image = cv2.imdecode(np.frombuffer(png.body(), np.uint8), cv2.IMREAD_COLOR)
    for label in OBJECT_LABELS:
        assert np.all(image == LABEL_BGR[label], axis=-1).sum() > 500, f"{label.word} is on the map"

    # What the Commander's canvas shows at each landmark is its colour; the legend names them all,
    # and the next target (the mug) is the one marked next.
    wait_js(commander, "document.getElementById('map').dataset.estimate !== undefined")
    maze = server.services.mazes.load(server.services.mazes.names()[0])
    for label in OBJECT_LABELS:
        x, y = maze.objects[label.word]
        rgb = commander.evaluate(
            """([x, y]) => { const c = document.getElementById('map');
            return [...c.getContext('2d').getImageData(Math.round(x / 2.4638 * c.width),
                                                       Math.round((1 - y / 2.0574) * c.height), 1, 1).data]; }""",
            [x, y],
        )
        assert tuple(rgb[2::-1]) == LABEL_BGR[label], label.word
    legend = commander.locator("#legend li[data-landmark]")
    assert sorted(t.strip() for t in legend.all_inner_texts()) == ["jar", "mug (next target)", "paddle"]
    assert commander.get_attribute("#legend li.next", "data-landmark") == "mug"

    # The Driver: their token, no token, a malformed one: never the map, never the landmarks.
    driver_token = driver_url.rsplit("/", 1)[-1]
    for url in (
        driver_url + "/map.png",
        f"{server.url}/play//map.png",
        f"{server.url}/play/map.png",
        f"{server.url}/play/{driver_token[:-2]}xx/map.png",
    ):
        answer = driver.request.get(url)
        assert answer.status in (403, 404), url
        assert answer.headers["content-type"].split(";")[0] != "image/png"
    assert "data-landmarks" not in driver.content()
    assert not any("map.png" in url for url in driver_requests)
    for page in (commander, driver):
        page.context.close()


def test_participants_see_the_clock_their_moves_and_what_to_do(browser, server, trials):
    services = server.services
    trial_id, commander_url, driver_url = new_trial(trials)
    commander, driver = seat_pages(browser, commander_url, driver_url)
    runtime = services.hub.peek(trial_id)
    assert "mark it on the map" in commander.inner_text("#status")
    assert "Tell the Commander what you see" in driver.inner_text("#status")
    assert driver.is_disabled("#found"), "nothing to claim before the robot is found"
    # On a laptop the Driver's chat shows a dozen messages or more, not six; both inputs on the screen.
    assert driver.locator(".chat ol").bounding_box()["height"] >= 450
    for page in (commander, driver):
        box = page.locator(".chat input").bounding_box()
        assert box["y"] + box["height"] <= 900, "the chat's input is on the screen without scrolling"

    click_map(commander, 0.5, 0.5)
    driver.wait_for_selector("#status[data-phase=navigating]")
    assert "Drive to target 1 of 3" in driver.inner_text("#status")
    for n in (1, 2):
        driver.click("#left")
        wait_until(
            lambda: runtime.state.moves == n and not runtime.state.moves_in_flight,  # noqa: B023  (waited on here)
            "a move",
        )
        driver.wait_for_selector(f"#moves[data-moves='{n}']")

    def seconds(page):
        return float(page.get_attribute("#clock", "data-seconds"))

    before = seconds(driver)
    wait_js(driver, f"Number(document.getElementById('clock').dataset.seconds) > {before}")
    wait_js(commander, f"Number(document.getElementById('clock').dataset.seconds) > {before}")

    # The experimenter pauses from the trial's page, saying why: the clocks stop, the status says
    # so with their words, and a refused move reads as what to do, not as the server's words.
    admin = experimenter(browser, server)
    admin.goto(f"{server.url}/experimenter/trials/{trial_id}")
    admin.wait_for_selector("#status[data-phase=navigating]")
    # Its watch socket brings the Driver's live camera and the true pose, for the experimenter only.
    admin.wait_for_selector("#camera[src^='data:image/jpeg']")
    admin.wait_for_selector("#pose-note >> text=True pose")
    assert admin.is_hidden("form.control-resume")
    admin.fill("form.control-pause input[name=reason]", "a short break")
    admin.click("form.control-pause button")
    for page in (commander, driver, admin):
        page.wait_for_selector("#status >> text=Paused by the experimenter (a short break). The clock is stopped.")
    admin.wait_for_selector("form.control-resume:not([hidden])")
    assert admin.is_hidden("form.control-pause")
    frozen = seconds(driver)
    driver.wait_for_timeout(600)
    assert seconds(driver) == frozen and seconds(commander) == pytest.approx(frozen, abs=0.051)
    assert frozen == pytest.approx(round(runtime.state.active_s(), 1), abs=0.051)
    assert driver.is_disabled("#forward")
    driver.evaluate("document.getElementById('forward').disabled = false")  # a stale page still sends
    driver.click("#forward")
    driver.wait_for_selector("#move-note >> text=The trial is paused. Wait until it goes on.")
    words = driver.evaluate("""() => import('/static/trial.js').then(m =>
        m.friendlyError('a target can be claimed only while navigating'))""")
    assert words == "Wait until the Commander has marked where the robot is."

    admin.click("form.control-resume button")
    wait_js(driver, f"Number(document.getElementById('clock').dataset.seconds) > {frozen}")
    assert runtime.state.moves == 2

    # Abort asks first: dismissed, nothing happens; accepted, every page says the trial ended.
    board = admin.context.new_page()  # the dashboard, open meanwhile
    board.goto(f"{server.url}/experimenter")
    board.locator(f"tr[data-trial='{trial_id}'] a.join-driver").wait_for()
    admin.wait_for_selector("form.control-abort:not([hidden])")
    admin.once("dialog", lambda d: d.dismiss())
    admin.click("form.control-abort button")
    admin.wait_for_timeout(300)
    assert not runtime.state.over
    admin.once("dialog", lambda d: d.accept())
    admin.click("form.control-abort button")
    for page in (commander, driver):
        page.wait_for_selector("#status[data-phase=aborted]")
        assert "ended early" in page.inner_text("#status")
    assert all(driver.is_disabled(b) for b in ("#forward", "#left", "#right", "#found"))
    admin.wait_for_selector("#status[data-phase=aborted]")  # the trial's page follows without a reload
    # The experimenter is told what it means and what they can do, not to close the page.
    assert "close this page" not in admin.inner_text("#status")
    assert "Restart it from the dashboard" in admin.inner_text("#status")
    assert all(admin.is_hidden(f"form.control-{a}") for a in ("pause", "resume", "abort"))
    assert commander.is_disabled("#chat-input")
    # The dashboard open meanwhile and one opened now: the ended trial's join links (which lead only
    # to a closed page) give way to its replay.
    for page in (board, admin):
        if page is admin:
            admin.goto(f"{server.url}/experimenter")
        row = page.locator(f"tr[data-trial='{trial_id}']")
        row.locator(".phase", has_text="aborted").wait_for()
        row.locator("a.replay").wait_for()
        assert row.locator("a.join-commander, a.join-driver").count() == 0
        assert all(row.locator(f"form.control-{a}").is_hidden() for a in ("pause", "resume", "abort"))
    for page in (commander, driver, admin):
        page.context.close()


def test_localize_by_keyboard_and_by_touch_and_take_the_seat_back(browser, server, trials):
    trial_id, commander_url, driver_url = new_trial(trials)
    commander, driver = seat_pages(browser, commander_url, driver_url)
    runtime = server.services.hub.peek(trial_id)

    commander.focus("#map")
    for key in ["ArrowRight"] * 4 + ["ArrowUp"] * 2 + ["["] * 2:
        commander.keyboard.press(key)
    assert "facing north" in commander.inner_text("#cursor-note")
    commander.keyboard.press("Enter")
    driver.wait_for_selector("#status[data-phase=navigating]")
    estimate = runtime.state.localization
    assert (estimate.x, estimate.y) == pytest.approx((W_M / 2 + 0.2, H_M / 2 + 0.1))
    assert estimate.heading == pytest.approx(math.pi / 2)

    # A reload keeps the Commander's mark.
    shown = commander.get_attribute("#map", "data-estimate")
    commander.reload()
    commander.wait_for_selector("#status[data-phase=navigating]")
    assert commander.get_attribute("#map", "data-estimate") == shown

    # The same link opened on a phone (touch): the first window says so and offers to take it back.
    phone = browser.new_context(viewport={"width": 390, "height": 844}, has_touch=True, is_mobile=True).new_page()
    phone.goto(commander_url)
    phone.wait_for_selector("#status[data-phase=navigating]")
    commander.wait_for_selector("#elsewhere:not([hidden])")
    # Tapped once the phone's page has stopped moving (its fonts in, the map's box the same over two
    # looks); where the press met the map is kept, so a miss says whether the page or the tap moved.
    phone.evaluate("document.fonts.ready")
    box = still_box(phone, "#map")
    phone.evaluate(
        """() => { const map = document.getElementById("map");
        map.addEventListener("pointerdown", (ev) => { const r = map.getBoundingClientRect();
          window.pressed = {x: ev.clientX, y: ev.clientY, left: r.left, top: r.top, width: r.width, height: r.height}; },
        {capture: true}); }"""
    )
    phone.tap("#map", position={"x": box["width"] * 0.25, "y": box["height"] * 0.75})
    wait_until(lambda: runtime.state.localization.x == pytest.approx(W_M * 0.25, abs=0.01), "the tapped mark")
    pressed = phone.evaluate("window.pressed")
    assert runtime.state.localization.y == pytest.approx(H_M * 0.25, abs=0.01), f"box {box}, pressed {pressed}"
    commander.click("#take-back")
    phone.wait_for_selector("#elsewhere:not([hidden])")
    commander.wait_for_selector("#elsewhere", state="hidden")
    commander.wait_for_selector("#status[data-phase=navigating]")
    for page in (commander, driver, phone):
        page.context.close()


def test_leaderboard_ranks_agent_drivers_apart_and_says_who_drove(browser, server, trials):
    services = server.services
    trial_id, _, _ = new_trial(trials)
    with services.db.begin() as db:
        human = db.get(Trial, trial_id)
        team = db.get(Team, human.team_id)
        human.phase, human.active_s, human.moves = "finished", 100.0, 20
        db.add(
            Trial(
                team_id=team.id,
                maze=human.maze,
                targets=human.targets,
                backend="sim",
                driver="agent:dialog",
                commander_id=team.member_a_id,
                phase="finished",
                active_s=10.0,
                moves=15,
            )
        )
    page = browser.new_context(viewport={"width": 1280, "height": 900}).new_page()
    page.goto(server.url + "/leaderboard")
    row = page.locator("#leaderboard tbody tr", has_text=team.name)
    assert row.locator(".driver").inner_text() == f"{team.name} driver"
    assert row.locator("td").nth(3).inner_text() == "1", "the agent's trial is not the team's"
    assert row.locator("td").nth(4).inner_text() == "120.0"
    agent = page.locator("#agent-leaderboard tbody tr").first
    assert agent.locator(".agent").inner_text() == "agent:dialog"
    assert team.name in agent.locator(".partners").inner_text() and agent.locator(".seat").inner_text() == "driver"
    assert "25.0" in agent.inner_text()
    ARTIFACTS.mkdir(exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / "leaderboard-agents.png"), full_page=True)
    page.context.close()

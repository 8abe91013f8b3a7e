"""What the browser tests share: where screenshots go, the maze's size, the experimenter's page,
the checks every page passes, and a Driver's page that knows the way."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

from bench.live import REPO
from sim.core.dynamics import Action
from tests.app.trial_play import facing_action, oracle_action

# Debian's chromium, headless: never a browser Playwright downloads.
CHROMIUM = Path("/usr/bin/chromium")
FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]

ARTIFACTS = REPO / "test-artifacts"
W_M, H_M = 2.4638, 2.0574


def log_in(browser, server, name: str, password: str, lands_on: str, **context):
    """A new browser context logged in with the home page's form, on the page it lands on."""
    page = browser.new_context(**context).new_page()
    page.goto(server.url + "/")
    page.fill("input[name=name]", name)
    page.fill("input[name=password]", password)
    page.click("#login")
    page.wait_for_url(server.url + lands_on)
    return page


def experimenter(browser, server, **context):
    return log_in(browser, server, "eve", "correct horse", "/experimenter", **context)


def team_of_two(page) -> None:
    """On the experimenter's dashboard: participants Ada and Ben, and their team "Ada & Ben"."""
    for name in ("Ada", "Ben"):
        page.fill("input[aria-label='Participant name']", name)
        page.click("#add-participant")
    page.fill("input[aria-label='Team name']", "Ada & Ben")
    page.click("#add-team")


def trial_with_an_agent(browser, server, maze: str, seat: str, targets: str | None = None):
    """The experimenter creates a trial of Ada & Ben on `maze` with `agent:dialog` in `seat`
    (commander or driver); their dashboard page and the trial's id."""
    admin = experimenter(browser, server, viewport={"width": 1400, "height": 900})
    team_of_two(admin)
    admin.select_option("select[name=maze]", maze)
    if targets is not None:
        admin.fill("input[aria-label='Targets']", targets)
    admin.select_option(f"select[name={seat}]", "agent:dialog")
    admin.click("#create-trial")
    return admin, int(admin.get_attribute("tr[data-trial]", "data-trial"))


def mark_on_map(page, x: float = 0.4, y: float = 0.5) -> None:
    """The Commander marks the robot on the map: a press at (x, y) of its width and height, dragged
    to the right for the heading; it ends localization."""
    box = page.locator("#map").bounding_box()
    page.mouse.move(box["x"] + box["width"] * x, box["y"] + box["height"] * y)
    page.mouse.down()
    page.mouse.move(box["x"] + box["width"] * (x + 0.05), box["y"] + box["height"] * y)
    page.mouse.up()


def page_checks(page, name: str) -> None:
    """axe-core finds no serious or critical violation; the page has a main heading (h1); nothing
    scrolls sideways at 390 px; no image is a broken placeholder."""
    from axe_playwright_python.sync_playwright import Axe

    page.wait_for_load_state("load")
    page.wait_for_timeout(300)  # the page scripts draw and fetch once
    violations = [v for v in Axe().run(page).response["violations"] if v["impact"] in ("serious", "critical")]
    assert not violations, (name, [(v["id"], [n["target"] for n in v["nodes"]][:3]) for v in violations])
    assert page.locator("h1").count() >= 1, (name, "no h1")
    width = page.evaluate("() => [document.documentElement.scrollWidth, window.innerWidth]")
    assert width[0] <= width[1], (name, width)
    broken = page.evaluate("""() => [...document.images].filter(i => !i.hidden && i.getClientRects().length
        && !(i.complete && i.naturalWidth > 0)).map(i => i.id)""")
    assert not broken, (name, broken)


def wait_until(predicate: Callable[[], bool], what: str, timeout: float = 10.0) -> None:
    deadline = time.time() + timeout
    while not predicate():
        if time.time() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.02)


def still_box(page, selector: str) -> dict[str, float]:
    """The element's box once it is where it was a moment before (a page still laying out moves
    what a click or tap aims at between its aiming and its press)."""
    boxes = [page.locator(selector).bounding_box()]

    def still() -> bool:
        time.sleep(0.05)
        boxes.append(page.locator(selector).bounding_box())
        return boxes[-1] == boxes[-2]

    wait_until(still, f"{selector} to stay where it is")
    return boxes[-1]


KEYS = {Action.FORWARD: "ArrowUp", Action.LEFT: "ArrowLeft", Action.RIGHT: "ArrowRight"}
BUTTONS = {Action.FORWARD: "#forward", Action.LEFT: "#left", Action.RIGHT: "#right"}


def drive_page_to_target(services, trial_id: int, driver, on_move: Callable[[int], None] | None = None) -> None:
    """The Driver's page, its buttons and arrow keys in turn, drives the shortest path to the
    current target and turns to face it (a person who knows the way); `on_move(n)` before each."""
    runtime = services.hub.peek(trial_id)
    driver.wait_for_selector("#forward:enabled")  # a verdict just given: the page takes it first
    for n in range(400):
        if on_move is not None:
            on_move(n)
        action = oracle_action(services, trial_id)
        if action == Action.STOP:  # at the target: look at it before claiming
            action = facing_action(services, trial_id)
        if action == Action.STOP:
            return
        before = runtime.state.moves
        if n % 2:
            driver.keyboard.press(KEYS[action])
        else:
            driver.click(BUTTONS[action])
        wait_until(
            lambda: runtime.state.moves > before  # noqa: B023  (waited on here)
            and runtime.state.last_frame_id is not None
            and not runtime.state.moves_in_flight,
            "a move to execute",
        )
        driver.wait_for_selector("#camera[aria-busy=false]")  # the page has the result: it takes the next press
    raise AssertionError("the target was not reached in 400 moves")

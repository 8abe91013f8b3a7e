"""End to end in headless Chromium: a person-like script plays the Commander's page against the
agent Driver `agent:dialog` on a bundled maze. It asks what the Driver sees, marks it on the map,
then types free-text instructions, one at a time, each once the Driver has answered; the Driver
answers, holds still until told to move, reaches the first target and claims it. The script
plans its words as a person reading the map would, from where the robot truly is (the test
harness may look; the agent never does). Screenshots go to test-artifacts/."""

from __future__ import annotations

import time

import pytest
from sqlalchemy import select

from app.db.models import Event
from sim.agents.oracle_commander import OracleCommander
from sim.core.dynamics import snap_pose
from sim.core.observations import RayTable
from sim.trial.agent import SeatInfo
from sim.trial.percepts import PhaseBegan
from sim.trial.vocabulary import Phase, Role
from tests.app.live import add_experimenter, wait_js
from tests.e2e.pages import ARTIFACTS, experimenter, mark_on_map, team_of_two

MAZE = "gen-000"  # one of the mazes bundled in sim/tasks/mazes/
MAX_INSTRUCTIONS = 30

pytestmark = pytest.mark.browser


# The first Driver message after the Commander's message `text` among the chat's messages from
# `sent` on (null until there is one).
_ANSWER = """([sent, text]) => {
  const items = [...document.querySelectorAll('#messages li')].slice(sent);
  const mine = items.findIndex((li) => li.classList.contains('commander') && li.textContent.endsWith(text));
  const answer = mine < 0 ? undefined : items.slice(mine + 1).find((li) => li.classList.contains('driver'));
  return answer ? answer.innerText : null;
}"""


def say(page, text: str, timeout_s: float = 60.0) -> str:
    """Type a message in the Commander's chat and wait for the Driver's answer to it: its first
    message after this one in the chat. (Counting the Driver's messages before typing took one
    already on its way, sent before this message reached the Driver, for the answer.)"""
    sent = page.locator("#messages li").count()
    page.fill("#chat-input", text)
    page.press("#chat-input", "Enter")
    deadline = time.monotonic() + timeout_s
    while (answer := page.evaluate(_ANSWER, [sent, text])) is None:
        if time.monotonic() > deadline:
            raise AssertionError(f"no answer from the Driver to {text!r} within {timeout_s} s")
        page.wait_for_timeout(50)
    return str(answer).removeprefix("Driver ")


def held_still(runtime, seconds: float) -> bool:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if runtime.state.move_ids:
            return False
        time.sleep(0.05)
    return True


def settled(runtime, quiet_s: float = 0.8, timeout_s: float = 20.0) -> None:
    """As a person watching the chat waits for the Driver to carry its instruction out: until no
    move has been asked for a while (a loaded machine slows the moves, not the person)."""
    deadline = time.monotonic() + timeout_s
    seen, since = len(runtime.state.move_ids), time.monotonic()
    while time.monotonic() < deadline:
        time.sleep(0.05)
        now = len(runtime.state.move_ids)
        if now != seen or runtime.state.moves_in_flight:
            seen, since = now, time.monotonic()
        elif time.monotonic() - since >= quiet_s:
            return


@pytest.mark.slow
def test_a_commander_talks_the_dialog_agent_to_its_first_target(browser, start_server):
    ARTIFACTS.mkdir(exist_ok=True)
    server = start_server(min_move_interval_s=0.1)
    services = server.services
    add_experimenter(server)
    # The experimenter registers two participants, forms a team and creates a trial.
    admin = experimenter(browser, server, viewport={"width": 1400, "height": 900})
    team_of_two(admin)
    admin.select_option("select[name=maze]", MAZE)
    admin.fill("input[aria-label='Targets']", "mug, paddle, jar")
    admin.select_option("select[name=driver]", "agent:dialog")
    assert "stops after 300 moves per target" in admin.inner_text("#agent-caps")
    admin.click("#create-trial")
    trial_id = int(admin.get_attribute("tr[data-trial]", "data-trial"))
    commander_url = admin.get_attribute("a.join-commander", "href")

    page = browser.new_context(viewport={"width": 1280, "height": 860}).new_page()
    page.goto(commander_url)
    page.wait_for_selector("#status[data-phase=localizing]")
    runtime = services.hub.peek(trial_id)
    assert held_still(runtime, 1.0), "the agent moved before anyone spoke"
    described = say(page, "hi! what do you see?")
    assert held_still(runtime, 0.5), "asked what it sees, it drove off"

    # "The robot is here": a click with a drag for the heading ends localization.
    mark_on_map(page, 0.4, 0.5)
    page.wait_for_selector("#status[data-phase=navigating]")
    assert held_still(runtime, 1.0), "marked on the map, it drove off before it was told"

    # The person reads the map: where the robot is, where the mug is, and says the next step.
    maze, graph = services.mazes.load(MAZE), services.mazes.graph(MAZE)
    person = OracleCommander(graph, RayTable.build(maze, graph), [("mug", maze.objects["mug"])])
    person.reset(SeatInfo(Role.COMMANDER, 3))
    backend = runtime.robot.backend
    person.pose = snap_pose(graph, *backend.pose())
    (first,) = person.perceive(PhaseBegan(Phase.NAVIGATING, 0, 3))
    answers = [say(page, first.text)]
    for _ in range(MAX_INSTRUCTIONS):
        settled(runtime)
        if page.locator("#claim:not([hidden])").count():
            break
        person.pose = snap_pose(graph, *backend.pose())
        answers.append(say(page, person.instruction(plain="?" in answers[-1])))
    page.wait_for_selector("#claim:not([hidden])", timeout=30_000)
    wait_js(page, "document.getElementById('claim-image').src.startsWith('data:image/jpeg')")
    page.screenshot(path=str(ARTIFACTS / "agent-driver-claim.png"), full_page=True)
    page.click("#confirm")
    page.wait_for_selector("#claim[hidden]", state="attached")

    with services.db() as db:
        events = db.scalars(select(Event).where(Event.trial_id == trial_id).order_by(Event.seq)).all()
    said = [e.payload["text"] for e in events if e.kind == "chat" and e.payload["role"] == "driver"]
    assert described in said and all(a in said for a in answers)  # its words are Driver chat events
    kinds = [e.kind for e in events]
    first_move = kinds.index("move_requested")
    navigating = next(i for i, e in enumerate(events) if e.kind == "phase" and e.payload["phase"] == "navigating")
    assert navigating < first_move  # it held still while being localized
    (confirmed,) = [e.payload for e in events if e.kind == "target_confirmed"]
    assert confirmed["target"] == "mug" and confirmed["truly_within"]  # it reached the mug and claimed it

"""End to end in headless Chromium: a person plays the Driver's page against the agent Commander
`agent:dialog` on a bundled maze. The person reads the Commander's messages on the page, describes
what the camera shows, does what they are told with the page's buttons and presses "I found the
target" when the target is there; the Commander localizes them from their words, marks them on
the map, guides them and confirms the claim from its frame. The person's words and understanding
are scripted with the project's dialog Driver, fed what the page shows: the Commander's
messages, the phase, each move's outcome, and the camera's view, read from the simulator at the
robot's true pose (as a person sees it in the frame; the agent Commander never does). Screenshots
go to test-artifacts/."""

from __future__ import annotations

import time
from collections import deque

import pytest
from sqlalchemy import select

from app.db.models import Event
from sim.agents.dialog_driver import DialogDriver
from sim.core.dynamics import snap_pose
from sim.trial import agent as ta
from sim.trial import commands as c
from sim.trial import percepts as p
from sim.trial import vocabulary as v
from tests.app.live import add_experimenter
from tests.e2e.pages import ARTIFACTS, trial_with_an_agent

MAZE = "gen-000"  # one of the mazes bundled in sim/tasks/mazes/
LEG_S = 300  # the first target, on a loaded 2-core machine (about a minute alone)
BUTTONS = {v.Move.FORWARD: "#forward", v.Move.LEFT: "#left", v.Move.RIGHT: "#right"}

pytestmark = pytest.mark.browser


class Person:
    """The Driver at the page: what it shows goes to the scripted mind, what the mind does goes
    through the page's chat and buttons."""

    def __init__(self, page, services, trial_id: int) -> None:
        self.page, self.services = page, services
        self.runtime = services.hub.peek(trial_id)
        self.graph, self.rays = services.mazes.graph(MAZE), services.mazes.rays(MAZE)
        self.mind = DialogDriver(seed=7)
        self.mind.reset(ta.SeatInfo(v.Role.DRIVER, 3))
        self.percepts: deque[p.Percept] = deque()
        self.read = 0  # the Commander's messages read so far
        self.phase: str | None = None
        self.frames = 0
        self.said: list[str] = []

    def view(self) -> p.Saw:
        """What the camera shows now (the simulator's view at the robot's pose)."""
        self.frames += 1
        pose = snap_pose(self.graph, *self.runtime.robot.backend.pose())
        return p.Saw(self.frames, self.rays.observation(*pose))

    def look(self) -> bool:
        """Read the page: a new phase, new Commander messages. Whether there was anything new."""
        phase = self.page.get_attribute("#status", "data-phase")
        new = False
        if phase != self.phase and phase in ("localizing", "navigating"):
            self.phase, new = phase, True
            self.percepts.append(p.PhaseBegan(v.Phase(phase), 0, 3))
            if phase == "localizing":
                self.percepts.append(self.view())
        lines = self.page.locator("#messages li.commander").all_inner_texts()
        for line in lines[self.read :]:
            self.percepts.append(p.Heard(v.Role.COMMANDER, line.removeprefix("Commander ").strip()))
            new = True
        self.read = len(lines)
        return new

    def think(self) -> None:
        while self.percepts:
            for turn in self.mind.perceive(self.percepts.popleft()):
                self.act(turn)

    def act(self, turn: c.Action) -> None:
        page = self.page
        match turn:
            case c.Say(text=text):
                page.fill("#chat-input", text)
                page.press("#chat-input", "Enter")
                self.said.append(text)
            case c.RequestMove(move=move):
                bumped = self.press(BUTTONS[move])
                self.percepts.append(p.Moved(move, v.Outcome.COLLISION if bumped else v.Outcome.OK))
                self.percepts.append(self.view())
            case c.Claim():
                page.wait_for_selector("#found:enabled")
                page.click("#found")
                page.wait_for_selector("#move-note >> text=/Confirmed|not it/", timeout=30_000)
                confirmed = "Confirmed" in page.inner_text("#move-note")
                self.percepts.append(p.Judged(confirmed, 0))
                if confirmed:
                    raise Reached

    def press(self, button: str) -> bool:
        """One move with the page's button, pressed again where the page refused it (too soon after
        the last one, as a quick person's press is); whether the robot bumped into something."""
        page = self.page
        for _ in range(20):
            before = page.inner_text("#moves")
            page.wait_for_selector(f"{button}:enabled")
            page.wait_for_timeout(150)  # a person's pace: no sooner than the server takes a move
            page.click(button)
            for _ in range(300):
                note = page.inner_text("#move-note")
                if page.inner_text("#moves") != before:
                    return "Bump" in note
                if note and "Bump" not in note and "still moving" not in note:
                    break  # refused: press again
                page.wait_for_timeout(50)
        raise AssertionError(f"the page never took a move: {page.inner_text('#move-note')!r}")


class Reached(Exception):
    """The first target is confirmed."""


@pytest.mark.slow
def test_a_person_drives_to_the_first_target_guided_by_the_agent_commander(browser, start_server):
    ARTIFACTS.mkdir(exist_ok=True)
    server = start_server(min_move_interval_s=0.1)
    services = server.services
    add_experimenter(server)
    # The experimenter registers two participants, forms a team and creates a trial.
    admin, trial_id = trial_with_an_agent(browser, server, MAZE, "commander", targets="mug, paddle, jar")
    assert admin.locator("a.join-commander").count() == 0, "no link for the agent's seat"
    assert "Commander agent:dialog" in admin.inner_text(f'tr[data-trial="{trial_id}"] .seats')
    driver_url = admin.get_attribute("a.join-driver", "href")

    page = browser.new_context(viewport={"width": 1280, "height": 860}).new_page()
    page.goto(driver_url)
    page.wait_for_selector("#status[data-phase=localizing]")
    page.wait_for_selector("#camera:not([hidden])")
    person = Person(page, services, trial_id)
    deadline = time.monotonic() + LEG_S
    try:
        while time.monotonic() < deadline:
            if not person.look():
                page.wait_for_timeout(100)
            person.think()
        raise AssertionError(f"no confirmation in {LEG_S} s; the person said {person.said[-5:]}")
    except Reached:
        pass
    page.screenshot(path=str(ARTIFACTS / "agent-commander-driver.png"), full_page=True)

    with services.db() as db:
        events = db.scalars(select(Event).where(Event.trial_id == trial_id).order_by(Event.seq)).all()
    chat = [(e.payload["role"], e.payload["text"]) for e in events if e.kind == "chat"]
    assert all(("driver", text) in chat for text in person.said), "the person's words are Driver chat events"
    assert any(role == "commander" and "?" in text for role, text in chat), "the Commander asked"
    marks = [e.payload for e in events if e.kind == "localization"]
    assert marks, "the agent Commander marked the robot on the map, as a person does"
    (confirmed,) = [e.payload for e in events if e.kind == "target_confirmed"]
    assert confirmed["target"] == "mug" and confirmed["truly_within"], "confirmed with the robot truly at the mug"

"""An agent in the Commander's seat, live: it hears what a person's Commander page gets and acts
through the same trial path; agents in both seats play a whole leg on the simulator."""

from __future__ import annotations

import asyncio
import re
import time

import pytest
from sqlalchemy import select

from app.db.models import Event, Trial
from app.seats.base import Seating
from app.seats.dialog import dialog_commander
from app.seats.registry import register_agent
from sim.trial import agent as ta
from sim.trial import commands as c
from sim.trial import events as ev
from sim.trial import percepts as p
from sim.trial import vocabulary as v
from sim.trial.events import LoggedEvent
from sim.trial.vocabulary import Role
from tests.app.live import Watch, experimenter_client, session_cookie

MAZE = "gen-000"  # bundled in sim/tasks/mazes/
LEG_S = 240  # a whole leg on a loaded 2-core machine; it takes about 5 s alone
COMMANDER_HEARS = (p.Heard, p.PhaseBegan, p.Claimed, p.Judged, p.PauseSet, p.Declined)


async def first_target_confirmed(server, trial_id: int, client) -> list[dict]:
    """Watch the trial as the experimenter (which opens it) until the first target is confirmed."""
    cookie = session_cookie(client).split("=", 1)[1]
    async with Watch(server, trial_id, cookie) as watch:
        await watch.event("target_confirmed", timeout=LEG_S, target_index=0)
        return list(watch.received)


def logged(services, trial_id: int) -> list[LoggedEvent]:
    with services.db() as db:
        rows = db.scalars(select(Event).where(Event.trial_id == trial_id).order_by(Event.seq)).all()
        return [LoggedEvent(r.seq, r.kind, r.t_ns, dict(r.payload)) for r in rows]


@pytest.mark.slow
@pytest.mark.settings(min_move_interval_s=0.05)
def test_the_commander_agent_hears_no_pose_no_frame_stream_and_no_moves(server, trials):
    services = server.services
    heard: list[p.Percept] = []
    seatings: list[Seating] = []

    class Listening:
        """`agent:dialog` as the Commander, keeping every percept its seat hands it."""

        def __init__(self, seating: Seating) -> None:
            seatings.append(seating)
            self.agent = dialog_commander(services, seating)

        def reset(self, info: ta.SeatInfo) -> None:
            self.agent.reset(info)

        def perceive(self, percept: p.Percept) -> list[c.Action]:
            heard.append(percept)
            return self.agent.perceive(percept)

    register_agent(Role.COMMANDER, "agent:test-listening", lambda services, seating: Listening(seating))
    trial = trials.new(maze=MAZE, commander="agent:test-listening", driver="agent:dialog")
    asyncio.run(first_target_confirmed(server, trial.id, experimenter_client(services, server.url)))
    # The watcher hears the confirmation as it is logged; the agent's seat hands it on in its own
    # time (later on a loaded machine).
    deadline = time.monotonic() + 30
    while not any(isinstance(q, p.Judged) and q.confirmed for q in heard):
        assert time.monotonic() < deadline, "the Commander agent never heard its claim confirmed"
        time.sleep(0.05)

    # The map, nothing that cheats, and that its partner is an agent (no read-back owed to a person).
    assert seatings == [Seating(seed=trial.id, oracle=None, maze=MAZE, partner_human=False)]
    assert heard and all(isinstance(q, COMMANDER_HEARS) for q in heard), {type(q).__name__ for q in heard}
    assert services.hub.peek(trial.id).state.moves > 0, "the robot moved, and the Commander never heard a move"
    said = [q for q in heard if isinstance(q, p.Heard)]
    assert {q.speaker for q in said} == {v.Role.COMMANDER, v.Role.DRIVER}
    legs = [q for q in heard if isinstance(q, p.PhaseBegan) and q.phase == v.Phase.NAVIGATING]
    assert legs[0].target == "mug", "the Commander's page learns the target as the trial reaches it"
    claims = [q for q in heard if isinstance(q, p.Claimed)]
    # The claim frame, read from its pixels as a person's page shows it: 13 rays, never a pose.
    assert claims and all(c.rays is not None and len(c.rays.labels) == 13 for c in claims)


@pytest.mark.slow
@pytest.mark.settings(min_move_interval_s=0.05)
def test_agents_in_both_seats_reach_the_first_target_through_the_trial_log(server, trials):
    services = server.services
    client = experimenter_client(services, server.url)
    trial = trials.new(maze=MAZE, commander="agent:dialog", driver="agent:dialog")
    watched = asyncio.run(first_target_confirmed(server, trial.id, client))

    events = logged(services, trial.id)
    typed = [ev.typed(e) for e in events]
    assert all(e is not None for e in typed), "every event is an ordinary, typed event"
    chat = [e for e in typed if isinstance(e, ev.Chat)]
    assert {c.role for c in chat} == {Role.COMMANDER, Role.DRIVER}
    assert any(isinstance(e, ev.Localized) for e in typed), "the Commander marked the robot on the map"
    assert {e.role for e in typed if isinstance(e, ev.Connected)} == {Role.COMMANDER, Role.DRIVER}
    assert sum(isinstance(e, ev.MoveExecuted) for e in typed) > 0
    confirmed = [e for e in typed if isinstance(e, ev.TargetConfirmed)]
    assert confirmed[0].target == "mug" and confirmed[0].truly_within, "confirmed with the robot truly there"
    assert not [e for e in typed if isinstance(e, ev.BadMessage)]
    assert any(m.get("kind") == ev.TargetConfirmed.kind for m in watched)

    with services.db() as db:
        row = db.get(Trial, trial.id)
        assert (row.team_id, row.commander, row.driver) == (None, "agent:dialog", "agent:dialog")
    row = re.search(rf'data-trial="{trial.id}".*?</tr>', client.get("/experimenter").text, re.S).group(0)
    assert "Commander agent:dialog · Driver agent:dialog" in row and "join-" not in row, "no join links for agents"


def test_the_trial_form_seats_agents_in_either_seat_and_starts_an_agent_pair_at_once(server):
    services = server.services
    client = experimenter_client(services, server.url)
    page = client.get("/experimenter").text
    commander = re.search(r'<select name="commander">.*?</select>', page, re.S).group(0)
    assert 'value="human"' in commander and 'value="agent:dialog"' in commander
    page = client.post("/experimenter/trials", data={"commander": "agent:dialog", "driver": "agent:dialog"}).text
    with services.db() as db:
        pair = db.scalar(select(Trial))
    assert pair is not None and pair.team_id is None, page
    runtime = services.hub.peek(pair.id)
    assert runtime is not None and runtime.state.commander == "agent:dialog", "started with nobody to open a link"

    for name in ("Ada", "Ben"):
        client.post("/experimenter/participants", data={"name": name})
    client.post("/experimenter/teams", data={"name": "Pair", "member_a": 1, "member_b": 2})
    page = client.post("/experimenter/trials", data={"team_id": 1, "commander": "agent:nobody"}).text
    assert "neither &#39;human&#39; nor a known agent for the commander&#39;s seat" in page
    page = client.post("/experimenter/trials", data={"team_id": 1, "commander": "agent:dialog", "commander_id": 2}).text
    with services.db() as db:
        mixed = db.scalar(select(Trial).where(Trial.team_id == 1))
    assert (mixed.commander, mixed.commander_id, mixed.driver, mixed.driver_id) == ("agent:dialog", None, "human", 2)
    row = re.search(rf'data-trial="{mixed.id}".*?</tr>', page, re.S).group(0)
    links = dict(re.findall(r'class="join-(\w+)" href="([^"]+)"', row))
    assert set(links) == {"driver"} and "Commander agent:dialog · Driver Ben" in row


@pytest.mark.settings(min_move_interval_s=0.05, agent_messages_per_target=3)
def test_agents_that_talk_past_their_message_cap_end_the_trial_saying_why(server, trials):
    services = server.services
    client = experimenter_client(services, server.url)
    trial = trials.new(maze=MAZE, commander="agent:dialog", driver="agent:dialog")

    async def watch() -> dict:
        async with Watch(server, trial.id, session_cookie(client).split("=", 1)[1]) as w:
            return await w.event("phase", timeout=60, phase="aborted")

    aborted = asyncio.run(watch())
    assert re.fullmatch(r"agent (Commander|Driver)'s cap: 3 messages for target 1", aborted["payload"]["reason"])
    typed = [ev.typed(e) for e in logged(services, trial.id)]
    chat = [e for e in typed if isinstance(e, ev.Chat)]
    assert "the most an agent may; I stop here" in chat[-1].text
    assert max(sum(c.role == role for c in chat[:-1]) for role in (Role.COMMANDER, Role.DRIVER)) <= 3

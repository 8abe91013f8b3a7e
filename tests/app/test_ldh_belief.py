"""The LDH model's live belief on the experimenter's watch socket: after each chat message of
the localization phase, from the colours baseline or a configured checkpoint; never on a
participant's socket, and no more once the Commander has localized the robot."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

from app.db.models import Experimenter
from app.security import hash_password
from sim.core.navgraph import NavGraph
from sim.tasks.ldh_eval import MazeContext, colour_logits
from sim.tasks.ldh_features import maze_views, mentions
from tests.app.live import TrialHandle, Watch, platform_settings
from tests.app.trial_play import start_trial

SAID = "I see a red wall on my left and a yellow wall ahead of me"


def expected_node_p(maze, cache_dir, dialog, logits_of) -> tuple[NavGraph, np.ndarray]:
    """P(node) over the main component, computed here from the sim's parts."""
    graph = NavGraph.build(maze, "benchmark", cache_dir=cache_dir)
    ctx = MazeContext(maze.name, graph, maze_views(maze, graph, cache_dir))
    logits = np.where(ctx.main[:, None], logits_of(mentions(dialog), ctx), -np.inf)
    p = np.exp(logits - logits.max()).sum(axis=1)
    return graph, p / p.sum()


@pytest.fixture
def ldh_model(tmp_path):
    """A learned localizer whose weights are away from the colours baseline, and its checkpoint file."""
    torch = pytest.importorskip("torch")
    from models.ldh import LDHConfig, Localizer, save

    torch.manual_seed(0)
    model = Localizer(dropout=0.5, prior=True)
    with torch.no_grad():  # so the two beliefs differ
        model.bilinear.normal_(0.0, 0.5)
    path = tmp_path / "best.pt"
    save(model, LDHConfig(), path)
    return model, path


@pytest.fixture
def settings(request, tmp_path):
    """The `server` fixture's settings here: a test that takes `ldh_model` has the server load it."""
    if "ldh_model" in request.fixturenames:
        return platform_settings(tmp_path, ldh_checkpoint=request.getfixturevalue("ldh_model")[1])
    return platform_settings(tmp_path)


def watch_a_localization(server, trial: TrialHandle):
    """`trial`'s two seats and a watcher through the localization phase; every message each one got."""
    services = server.services
    maze_name = services.mazes.names()[0]  # the `trial` fixture's
    with services.db.begin() as db:
        eve = Experimenter(name="eve", password_hash=hash_password("correct horse"))
        db.add(eve)
        db.flush()
        eve_id = eve.id
    cookie = services.sessions.issue(eve_id)

    async def play():
        async with (
            trial.seat("commander") as commander,
            trial.seat("driver") as driver,
            Watch(server, trial.id, cookie) as watch,
        ):
            await start_trial(commander, driver)
            await commander.send("chat", text="what do you see?")
            await watch.wait_for(lambda m: m.get("type") == "ldh_belief")
            await driver.send("chat", text=SAID)
            said = await watch.wait_for(lambda m: m.get("kind") == "chat" and m["payload"]["text"] == SAID)
            belief = await watch.wait_for(lambda m: m.get("type") == "ldh_belief" and m["upto_seq"] == said["seq"])
            async with Watch(server, trial.id, cookie) as late:  # a watcher that opens the page now
                on_open = await late.wait_for(lambda m: m.get("type") == "ldh_belief")
            await commander.send("localize", x=1.0, y=1.0, heading=None)
            await watch.wait_for(lambda m: m.get("type") == "status" and m["phase"] == "navigating")
            await driver.send("chat", text="moving on, the blue wall is behind me")
            await watch.wait_for(lambda m: m.get("kind") == "chat" and "blue" in m["payload"]["text"])
            await commander.send("chat", text="good")
            await watch.wait_for(lambda m: m.get("kind") == "chat" and m["payload"]["text"] == "good")
            return commander, driver, watch, belief, on_open

    return services.mazes.load(maze_name), asyncio.run(play())


def check(maze, settings, run, logits_of, model: str) -> None:
    commander, driver, watch, belief, on_open = run
    dialog = (("oracle", "what do you see?"), ("navigator", SAID))
    graph, node_p = expected_node_p(maze, settings.cache_dir, dialog, logits_of)
    assert belief["model"] == model and on_open["top"] == belief["top"]
    top = np.asarray(belief["top"])
    assert (np.diff(top[:, 2]) <= 0).all() and top[:, 2].sum() <= 1.0 + 1e-6
    best = int(node_p.argmax())
    assert top[0, :2] == pytest.approx(graph.nodes[best], abs=1e-4)
    assert top[0, 2] == pytest.approx(node_p[best], abs=1e-5)
    assert node_p[best] > 2 / graph.n  # the colours named make some places much likelier than the rest
    beliefs = [m for m in watch.received if m.get("type") == "ldh_belief"]
    navigating = next(i for i, m in enumerate(watch.received) if m.get("phase") == "navigating")
    assert all(watch.received.index(m) < navigating for m in beliefs)  # none once localized
    for seat in (commander, driver):  # never to a participant
        assert not [m for m in seat.received if m.get("type") == "ldh_belief"]


def test_the_colours_belief_follows_the_dialog(settings, server, trial):
    maze, run = watch_a_localization(server, trial)
    check(maze, settings, run, lambda counts, ctx: colour_logits(counts, ctx.views), "colours")


def test_a_configured_checkpoint_gives_the_learned_belief(ldh_model, settings, server, trial):
    from models.ldh import TrainedLocalizer

    model, _ = ldh_model
    maze, run = watch_a_localization(server, trial)
    learned = TrainedLocalizer(model)
    check(maze, settings, run, learned.logits, "learned")
    _, colours = expected_node_p(
        maze, settings.cache_dir, (("navigator", SAID),), lambda counts, ctx: colour_logits(counts, ctx.views)
    )
    _, trained = expected_node_p(maze, settings.cache_dir, (("navigator", SAID),), learned.logits)
    assert not np.allclose(colours, trained)

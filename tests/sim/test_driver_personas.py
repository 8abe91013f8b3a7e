"""The frozen Driver personas: each is the file that was frozen, loads, and words every kind of
thing the dialog Driver says in its own templates, slips drawn from its seed; a whole self-play
trial with a persona in the Driver's seat runs on a bundled maze."""

from __future__ import annotations

import hashlib
import re
import shutil

import pytest

from sim.agents.selfplay import CommanderName, DriverName, Job, library_trials, run_job, world
from sim.core.labels import Label
from sim.language import driver_personas
from sim.language.driver_personas import DRIVER_PERSONA_SHA256, DriverPersona, Message, load_driver_persona
from sim.language.driver_phrasing import (
    Answered,
    Claiming,
    Described,
    Done,
    Fact,
    NotHere,
    PersonaDriverPhrasing,
    ScriptedDriverPhrasing,
    Stopped,
    Stuck,
    Trouble,
    Troubled,
    Why,
)
from sim.language.vocab import Side

MAZE = "gen-000"


@pytest.fixture(scope="module")
def views():
    """The four sides' views from a node of a bundled maze that sees walls on every side."""
    _, graph, rays = world(None, MAZE)
    node = max(
        range(len(graph.nodes)), key=lambda n: sum(int(rays.labels[n, h].astype(bool).sum()) for h in (0, 2, 4, 6))
    )
    return {side: rays.observation(node, heading) for side, heading in zip(Side, (0, 2, 4, 6), strict=True)}


def test_each_persona_is_the_file_that_was_frozen(tmp_path, monkeypatch):
    for persona in DriverPersona:
        assert hashlib.sha256(persona.path.read_bytes()).hexdigest() == DRIVER_PERSONA_SHA256[persona]
    edited = tmp_path / "driver_terse.json"
    shutil.copy(DriverPersona.TERSE.path, edited)
    edited.write_text(edited.read_text().replace('"yep"', '"yeah"'))
    monkeypatch.setattr(driver_personas, "PERSONAS_DIR", tmp_path)
    with pytest.raises(ValueError, match="never edited"):
        load_driver_persona(DriverPersona.TERSE)


def _facts(views) -> list[Fact]:
    ahead = views[Side.AHEAD]
    return [
        Described(views, look_around=True),
        Described({Side.LEFT: views[Side.LEFT]}, look_around=False),
        Answered(Label.RED, Side.LEFT, views[Side.LEFT]),
        Answered(Label.MUG, Side.AHEAD, ahead),
        Done("turned left", ahead),
        Done("", None),
        Stopped(ahead),
        *(Stuck(why, 3, ahead) for why in Why),
        Claiming(Label.PADDLE),
        NotHere(),
        *(Troubled(trouble, quoted="go left", detail="turn left") for trouble in Trouble),
    ]


@pytest.mark.parametrize("persona", list(DriverPersona))
def test_a_persona_words_every_fact_from_its_own_templates(persona, views):
    phrasing = PersonaDriverPhrasing(persona, seed=1)
    book = phrasing.book
    for fact in _facts(views):
        text = phrasing.say(fact)
        assert text.strip() and not re.search(r"[{}]", text), (fact, text)
    # The view: every side it looked at is named in the persona's words, not the scripted Driver's.
    said = phrasing.say(Described(views, look_around=True))
    assert ScriptedDriverPhrasing().say(Described(views, look_around=True)) != said
    assert any(name in said for name in book.sides[Side.AHEAD] + book.sides[Side.BEHIND])
    # A walk stopped short says how far it got, in the persona's numbers.
    blocked = [phrasing.say(Stuck(Why.CANNOT_GO, 3, None)) for _ in range(20)]
    three = "three" if book.numbers == "words" else "3"
    assert any(three in text for text in blocked)
    assert all(_from(text, book.says[Message.BLOCKED]) for text in blocked)
    claims = {phrasing.say(Claiming(Label.MUG)) for _ in range(20)}
    assert all(_from(claim, book.says[Message.CLAIM]) for claim in claims)
    # (a terse "there" names nothing)
    assert any(any(name in claim for name in book.things.get("mug", ["mug"])) for claim in claims)


def _from(text: str, templates: list[str]) -> bool:
    """`text` is one of `templates` with its slots filled."""
    return any(re.fullmatch(re.sub(r"\\\{\w+\\\}", ".*", re.escape(t)), text, re.DOTALL) for t in templates)


def test_the_same_seed_says_the_same_words_and_slips_are_one_step_at_most(views):
    said = [[PersonaDriverPhrasing(DriverPersona.UNSURE, seed=7).say(f) for f in _facts(views)] for _ in range(2)]
    assert said[0] == said[1]
    unsure = PersonaDriverPhrasing(DriverPersona.UNSURE, seed=3)
    counts = [unsure.count(5) for _ in range(2000)]
    assert set(counts) == {4, 5, 6}
    # Its rate (0.1) as frozen, within sampling error.
    assert 0.07 < sum(c != 5 for c in counts) / len(counts) < 0.13
    assert all(PersonaDriverPhrasing(DriverPersona.TERSE, seed=s).count(1) == 1 for s in range(50))


def test_a_whole_trial_with_a_persona_driver():
    """The terse persona in the Driver's seat against the dialog Commander, on a bundled maze: the
    Driver speaks only in the persona's words and the trial plays to its end."""
    maze, graph, _ = world(None, MAZE)
    spec = library_trials([(MAZE, maze)], [graph])[0]
    result = run_job(Job(spec, CommanderName.DIALOG, DriverName.PERSONA_TERSE))
    driver_said = [text for role, text in result.dialog if role == "driver"]
    assert driver_said and not any("what next?" in text or "i think i found" in text for text in driver_said)
    assert result.completed, result.dialog

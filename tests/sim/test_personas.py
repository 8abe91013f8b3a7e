"""The frozen Commander personas: each loads only as frozen and fills every kind of instruction."""

from __future__ import annotations

import pytest

from sim.language import phrases
from sim.language.phrases import Persona, PhraseKind, Phrases

SLOTS = {"thing": "coffee mug", "n": 3, "turn": "turn left", "wall": "red wall"}


@pytest.mark.parametrize("persona", list(Persona))
def test_each_persona_says_every_instruction_in_full(persona):
    said = Phrases(persona, seed=1)
    for _ in range(8):  # several draws: every template of a kind is reached
        for kind in PhraseKind:
            text = said.say(kind, **SLOTS)
            assert text and "{" not in text and "}" not in text
        for eighths in (1, 2, 3, 4, -1, -2, -3):
            turn = said.turn(eighths)
            assert turn and "{" not in turn


def test_the_metric_persona_counts_centimetres():
    assert Phrases(Persona.METRIC).number(3) == "21"
    assert "21" in Phrases(Persona.METRIC).say(PhraseKind.FORWARD, n=3)


def test_an_edited_persona_is_refused(tmp_path, monkeypatch):
    edited = tmp_path / "commander_terse.json"
    edited.write_bytes(Persona.TERSE.path.read_bytes().replace(b"{n}", b"{n} steps", 1))
    monkeypatch.setattr(phrases, "PERSONAS_DIR", tmp_path)
    with pytest.raises(ValueError, match="not the frozen persona"):
        Phrases(Persona.TERSE)

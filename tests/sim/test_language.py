"""The maze language on the train split's Commander sentences (never val/test): what the Driver
understands, including negation, counts, history and typos, and how it describes a view."""

import numpy as np

from sim.core.labels import Label
from sim.core.rays import RayObservation
from sim.language.describe import describe
from sim.language.instructions import (
    Ask,
    AskedAbout,
    Forward,
    GoBack,
    Place,
    Stop,
    TakeOpening,
    Target,
    Turn,
    parse,
)
from sim.language.sectors import Sector
from sim.language.vocab import Side, correct
from sim.tasks.ldh_features import mentions


def test_turns_and_walks_of_train_sentences_keep_their_order():
    assert parse(
        "Continue forward and make a left turn at the white wall and then a U turn after that"
    ).instructions == (
        Forward(until=Label.WHITE),
        Turn(2),
        Turn(4),
    )
    assert parse("And make a u-turn around the yellow wall").instructions == (Turn(4),)


def test_acknowledgements_ask_nothing_and_expectations_are_checked():
    assert parse("Got it").instructions == () and not parse("Got it").unclear
    assert parse("now the  mug").instructions == (Target(Label.MUG),)
    assert parse("You should then have red on your left and blue on your right").instructions[0] == Ask(
        AskedAbout.IS_THERE, Side.LEFT, Label.RED
    )


def test_typos_are_read_as_the_words_meant():
    assert parse("then turn rihgt").instructions == (Turn(-2),)
    assert parse("move forward untill the end of blue walls").instructions == (Forward(until=Label.BLUE),)
    assert correct("yelow") == "yellow" and correct("foward") == "forward"
    assert correct("that") == "that" and correct("black") == "black" and correct("follow") == "follow"
    # Common words one edit from the maze's are left alone: "nice and straight" is not nine steps.
    assert [correct(w) for w in ("nice", "fine", "walk", "give")] == ["nice", "fine", "walk", "give"]
    # A person's chat: "for a while" had a white wall in it, "no clue" no blue one, "back and forth"
    # an ordinal, and "sounds good" was a claim.
    chat = ("while", "clue", "forth", "sound", "read", "year", "ground", "fellow")
    assert [correct(w) for w in chat] == list(chat)


def test_a_chats_shorthand_is_read_as_the_words_it_stands_for():
    assert parse("turn r").instructions == (Turn(-2),)
    assert parse("fwd 3 then l").instructions == (Forward(3), Turn(2))
    assert parse("u turn").instructions == (Turn(4),)


def test_history_points_back_to_the_start_or_a_turn():
    assert parse("Go back to where you started").instructions == (GoBack(Place.START),)
    assert parse("Go back to the area where you started").instructions == (GoBack(Place.START),)
    assert parse("go back to where you turned right first").instructions == (GoBack(Place.TURN, Side.RIGHT, 1),)


def test_negation_narrows_the_wall_to_stop_at():
    assert parse("turn left at the wall, not the red one").instructions == (
        Forward(exclude=frozenset({Label.RED})),
        Turn(2),
    )
    assert parse("go to the wall that is not red").instructions == (Forward(exclude=frozenset({Label.RED})),)


def test_counts_of_openings_turns_and_steps():
    assert parse("take the second left").instructions == (TakeOpening(Side.LEFT, 2),)
    assert parse("turn left twice").instructions == (Turn(2), Turn(2))
    assert parse("go forward about 5 steps, then turn right").instructions == (Forward(steps=5), Turn(-2))
    assert parse("move ahead five steps and take a right turn").instructions == (Forward(steps=5), Turn(-2))


def test_targets_questions_and_claim_cues():
    assert parse("And left again to find the  jar").instructions == (Target(Label.JAR), Turn(2))
    assert parse("Ok lets find the  paddle").instructions == (Target(Label.PADDLE),)
    assert parse("Your second objective is a black  coffee-mug").instructions == (Target(Label.MUG),)
    assert parse("The  jar will be on your left").instructions == (Target(Label.JAR, Side.LEFT),)
    assert parse("Is there a blue wall on your right?").instructions == (
        Ask(AskedAbout.IS_THERE, Side.RIGHT, Label.BLUE),
    )
    assert parse("Describe your surroundings.").instructions == (Ask(AskedAbout.VIEW),)
    assert parse("what is on your left?").instructions == (Ask(AskedAbout.SIDE, Side.LEFT),)
    assert parse("stop, you are there").instructions == (Stop(claim=True),)
    assert parse("wibble wobble").unclear


def _view(labels, depth):
    labels = np.array(labels, dtype=np.uint8)
    return RayObservation(
        labels=labels,
        depth=np.array(depth, dtype=np.float32),
        too_close=np.zeros(13, dtype=bool),
        valid=np.ones(13, dtype=bool),
        forward_blocked=False,
    )


def test_a_description_reads_back_as_the_sides_it_was_seen_on():
    ahead = _view([Label.RED] * 13, [0.3] * 13)
    left = _view([Label.BLUE] * 10 + [Label.MUG] * 3, [1.0] * 13)
    text = describe({Side.AHEAD: ahead, Side.LEFT: left})
    counts = mentions([("navigator", text)])
    assert counts[Sector.FRONT, Label.RED] == 1
    assert counts[Sector.LEFT, Label.BLUE] == 1 and counts[Sector.LEFT, Label.MUG] == 1
    assert counts[Sector.RIGHT].sum() == 0 and counts[Sector.BEHIND].sum() == 0

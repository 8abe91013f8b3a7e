"""What the Driver makes of a Commander's reading beyond its program form: a turn that goes on until
something is in view, the counts a reading leaves unused and where they go, and the read-back of a
plan with each turn's size. Sentences written for these tests, none from the benchmark's dialogs."""

import pytest

from sim.core.labels import Label
from sim.language import instructions as ins
from sim.language.meaning import Clause, FactForm, FactKind, Op
from sim.language.reader import counts
from sim.language.understanding import Understanding, instructing, instructions, read_back, unread_counts, with_count
from sim.language.vocab import Side

TURN_LEFT = Clause.of(Op.TURN, eighths=2)
TO_THE_MUG = Clause.of(Op.FORWARD, steps=None, until="mug")
TO_THE_JAR = Clause.of(Op.FORWARD, steps=None, until="jar")
_TO_A_WALL = Clause.of(Op.FORWARD, steps=None, until="wall")


def _walk(steps: int) -> Clause:
    return Clause.of(Op.FORWARD, steps=steps, until=None)


def test_a_turn_until_something_is_seen_is_read_from_the_words():
    assert ins.turn_until("turn left until you see the coffee mug") == ins.TurnUntil(
        Side.LEFT, Label.MUG, facing=False, walk=False
    )
    assert ins.turn_until("rotate till the red wall is in front of you") == ins.TurnUntil(
        None, Label.RED, facing=True, walk=False
    )
    assert ins.turn_until("keep spinning right till the jar is in view, then drive up to it") == ins.TurnUntil(
        Side.RIGHT, Label.JAR, facing=False, walk=True
    )
    # A walk said in the turn's clause, or nothing to see: no turn until.
    assert ins.turn_until("turn left and go until you see the mug") is None
    assert ins.turn_until("turn left until the end of the corridor") is None


def test_the_walk_read_into_until_you_see_it_is_dropped_and_the_turn_goes_on_until_then():
    text = "turn left until you see the coffee mug"
    assert instructions((TURN_LEFT, TO_THE_MUG), text) == [ins.Turn(2, Label.MUG)]
    # Read as a walk alone, or with the turn the wrong way: the words' turn, their way.
    assert instructions((TO_THE_MUG,), text) == [ins.Turn(2, Label.MUG)]
    assert instructions((Clause.of(Op.TURN, eighths=-2), TO_THE_MUG), text) == [ins.Turn(2, Label.MUG)]
    # A walk the message does say stays.
    said = "turn left until you see the coffee mug, then go up to it"
    assert instructions((TURN_LEFT, TO_THE_MUG), said) == [ins.Turn(2, Label.MUG), ins.Forward(until=Label.MUG)]
    assert read_back(instructions((TURN_LEFT, TO_THE_MUG), text)) == "turning left until i see the coffee mug"


def test_a_turn_said_to_be_made_several_times_is_made_that_many_times():
    # The reader learnt from the rules, which once knew only "twice": it reads one turn for these.
    reader, right = Understanding.trained(), Clause.of(Op.TURN, eighths=-2)
    assert reader.program("turn right 4 times").meaning == (right,) * 4
    assert reader.program("make two left turns and go to the mug").meaning == (TURN_LEFT, TURN_LEFT, TO_THE_MUG)
    assert ins.parse("left 3 times").instructions == (ins.Turn(2),) * 3
    assert ins.parse("turn left twice").instructions == (ins.Turn(2),) * 2
    # A number that counts no turns leaves the turn alone.
    assert ins.parse("turn right and go 3 steps").instructions == (ins.Turn(-2), ins.Forward(3))


def test_button_presses_are_counted_one_move_each_and_a_press_until_a_wall_is_a_walk():
    reader, left, right = Understanding.trained(), Clause.of(Op.TURN, eighths=1), Clause.of(Op.TURN, eighths=-1)
    assert reader.program("press left twice").meaning == (left, left)
    assert reader.program("Click the forward button 4 times, then right once").meaning == (_walk(4), right)
    assert reader.program("press left twice and go to the mug").meaning == (left, left, TO_THE_MUG)
    assert reader.program("press forward until you reach the mug").meaning == (TO_THE_MUG,)
    assert reader.program("go until you hit the mug").meaning == (TO_THE_MUG,)  # no button: a walk
    # The rules count them the same way: they read the dialog Commander's own turns, said as presses.
    assert ins.parse("press left twice, then go forward about 3 steps").instructions == (
        ins.Turn(1),
        ins.Turn(1),
        ins.Forward(3),
    )
    assert ins.parse("go forward until the white wall, then press right 3 times").instructions == (
        ins.Forward(None, Label.WHITE),
        *[ins.Turn(-1)] * 3,
    )
    assert ins.parse("click forward 4 times, then right once").instructions == (ins.Forward(4), ins.Turn(-1))


def test_clauses_that_say_where_the_driver_is_or_what_a_move_is_for_give_no_moves():
    """A person's, in the browser: "so you get above the white wall" had been a walk to it, "you're in
    the right place" a right turn, "facing a red wall" at the top left a left turn, "a dozen" and
    "thirty" no count, and the olive green paddle a green wall."""
    reader, right = Understanding.trained(), Clause.of(Op.TURN, eighths=-2)
    said = "Lovely. Now turn right and go forward about 4 steps, so you get above the white wall."
    assert reader.program(said).meaning == (right, _walk(4))
    said = "That's fine, you're in the right place. Now turn right and go forward about a dozen steps."
    assert reader.program(said).meaning == (right, _walk(12))
    said = "I've put my mark: I think you're in the corridor at the top left, facing a red wall. Let's find the paddle now."
    assert not [c for c in reader.program(said).meaning if c.op in (Op.TURN, Op.FORWARD)]
    assert (
        Clause.of(Op.EXPECT, label="green", side="any")
        not in reader.program("can you see the olive green paddle?").meaning
    )
    said = "Nearly there! Turn right and go up to the jar, the light blue one."
    assert not [c for c in reader.program(said).meaning if "blue" in c.args]  # it went to a blue wall
    assert instructing("go past the blue one") == "go past the blue one"  # a wall, maybe
    # What places or claims stays.
    assert instructing("you're at the jar now") == "you're at the jar now"
    assert instructing("got it, you are right by it") == "got it, you are right by it"


def test_a_move_said_not_to_be_made_and_a_right_that_means_directly_turn_nothing():
    """A person's "Oh no, I didn't ask you to turn right! ... Please turn left again and go to the mug."
    turned the agent right, and "If you're right next to the mug, go ahead and tell me you found it."
    turned it right and walked it off."""
    reader = Understanding.trained()
    said = "Oh no, I didn't ask you to turn right! The mug was just in front of you. Please turn left again and go to the mug."
    assert [c for c in reader.program(said).meaning if c.op != Op.TARGET] == [TURN_LEFT, TO_THE_MUG]
    said = "Brilliant! If you're right next to the mug, go ahead and tell me you found it."
    assert not [c for c in reader.program(said).meaning if c.op == Op.TURN]
    assert reader.program("don't turn left, turn right").meaning == (Clause.of(Op.TURN, eighths=-2),)
    assert reader.program("take a sharp right").meaning == (Clause.of(Op.TURN, eighths=-3),)
    # Chat and a correction of what was meant, from a second play: each had added a walk.
    around = Clause.of(Op.TURN, eighths=4)
    said = "Marvellous, two down and one to go! Now please turn around and go back up those twelve steps."
    assert reader.program(said).meaning == (around, Clause.of(Op.BACK, place="previous", steps=12))
    assert reader.program("u went 2 far lol. turn around n go back 2").meaning[0] == around
    said = "I didn't mean forward just then. Please press the right button three times."
    assert reader.program(said).meaning == (Clause.of(Op.TURN, eighths=-1),) * 3


def test_a_side_said_just_before_a_count_of_steps_is_a_turn_that_way_then_the_walk():
    reader, right = Understanding.trained(), Clause.of(Op.TURN, eighths=-2)
    assert reader.program("right 3").meaning == (right, _walk(3))
    assert reader.program("left 3").meaning == (TURN_LEFT, _walk(3))
    assert reader.program("forward 2 right 3").meaning == (_walk(2), right, _walk(3))
    assert reader.program("forward 2, left 3, right 1").meaning == (_walk(2), TURN_LEFT, _walk(3), right, _walk(1))
    # Where a wall is, a turn's size, and turns counted are no such walk.
    assert Op.TURN not in {c.op for c in reader.program("keep the wall on your right 3 steps").meaning}
    assert reader.program("right 45").meaning == (Clause.of(Op.TURN, eighths=-1),)
    assert reader.program("turn right 3 times").meaning == (right,) * 3


def test_an_opening_counted_in_words_is_taken_as_counted():
    reader = Understanding.trained()
    for text, side, nth in [
        ("take the second opening on your left", "left", 2),
        ("take the 2nd opening on the left", "left", 2),
        ("turn into the third gap to the right", "right", 3),
        ("take the next left", "left", 1),
    ]:
        assert Clause.of(Op.OPENING, side=side, nth=nth) in reader.program(text).meaning, text


def test_a_reading_names_no_colour_or_object_the_words_do_not():
    reader = Understanding.trained()
    # It read "the paddle should be on your left" into a turn that names no object.
    assert "paddle" not in str(reader.program("take the second opening on your left").meaning)
    # A turn that points back ("follow them") may name what an earlier turn did; "bat" is the paddle.
    assert reader.program("go up to it", ("d", "i can see the mug")).meaning == (TO_THE_MUG,)
    assert Clause.of(Op.FORWARD, steps=None, until="paddle") in reader.program("go to the ping pong bat").meaning


def test_a_driver_turn_states_a_view_only_in_words_that_state_one():
    reader = Understanding.trained()
    kinds = {FactKind.LABEL, FactKind.EDGE, FactKind.CORRIDOR, FactKind.CORNER, FactKind.DEAD_END}
    for text in ("and then i took a left", "where is the edge of the maze?", "i cannot turn right here"):
        assert not {f for f in reader.facts(text).meaning if f.kind in kinds}, text
    # A question without its "?" is still one.
    for text in ("where is the edge of the maze", "how many steps now", "should i take the next left"):
        assert FactForm.of(FactKind.QUESTION) in reader.facts(text).meaning, text
    # A "yes" is read against what it answers.
    yes = reader.facts("yes", ("c", "is there a red wall on your left?"), "is there a red wall on your left?")
    assert FactForm.of(FactKind.LABEL, label="red", side="left", distance="any", negated=False) in yes.meaning


def test_both_colours_of_a_pair_are_expected_and_a_turn_between_walls_is_made_at_the_first():
    reader = Understanding.trained()
    expected = [c for c in reader.program("now the orange and blue walls should be on your right").meaning]
    assert set(expected) >= {Clause.of(Op.EXPECT, label=colour, side="right") for colour in ("red", "blue")}
    assert reader.program("drive on, then take a left turn in between the yellow and white walls").meaning[-2:] == (
        Clause.of(Op.FORWARD, steps=None, until="yellow"),
        TURN_LEFT,
    )
    # Looking is not turning at a place.
    looked = reader.program("look left between the brown walls").meaning
    assert Clause.of(Op.FORWARD, steps=None, until="brown") not in looked


def test_a_walk_said_first_is_made_first():
    reader = Understanding.trained()
    assert reader.program("drive straight on and then follow the blue walls").meaning[0] == _TO_A_WALL
    assert reader.program("go forward, then turn right").meaning[0] == _TO_A_WALL
    # Following alone, or going back, is no walk first.
    assert reader.program("keep following the green walls").meaning[0] != _TO_A_WALL
    assert reader.program("go back the way you came").meaning[0].op == Op.BACK


def test_a_walk_said_last_is_made_last_and_what_to_face_is_checked_not_walked_to():
    reader = Understanding.trained()
    assert reader.program("spin around and then follow the hallway").meaning == (
        Clause.of(Op.TURN, eighths=4),
        _TO_A_WALL,
    )
    assert reader.program("turn around so that you face the yellow walls").meaning == (
        Clause.of(Op.TURN, eighths=4),
        Clause.of(Op.EXPECT, label="yellow", side="ahead"),
    )
    # Until it faces something: a walk there.
    assert reader.program("drive on until you are facing the red wall").meaning == (
        Clause.of(Op.FORWARD, steps=None, until="red"),
    )


def test_a_u_turn_said_with_a_side_turns_around_and_a_dropped_letter_keeps_the_side():
    reader = Understanding.trained()
    assert reader.program("now do a left u-turn").meaning == (Clause.of(Op.TURN, eighths=4),)
    assert reader.program("turn right and then a right uturn").meaning == (
        Clause.of(Op.TURN, eighths=-2),
        Clause.of(Op.TURN, eighths=4),
    )
    assert reader.program("the yellow walls will be on your lef").meaning == (
        Clause.of(Op.EXPECT, label="yellow", side="left"),
    )


def test_back_to_where_it_just_was_is_the_way_it_came_not_the_start():
    reader = Understanding.trained()
    assert [c.args[0] for c in reader.program("go back to where you were a moment ago").meaning] == ["previous"]
    assert reader.program("go back to where you started").meaning == (Clause.of(Op.BACK, place="start", steps=None),)


def test_a_read_back_says_each_turn_with_its_size():
    program = (TURN_LEFT, _walk(2), Clause.of(Op.TURN, eighths=-1), Clause.of(Op.TURN, eighths=4))
    assert read_back(instructions(program, "")) == (
        "turning left 90 degrees, then forward 2 steps, then turning right 45 degrees, then turning around"
    )


def test_counts_of_steps_exclude_angles_turns_and_the_word_one():
    assert [(c.steps, c.said) for c in counts("roll 21 cm then left 90, then 4 more")] == [(3, "21 cm"), (4, "4")]
    assert not any(c.of_steps for c in counts("make two right turns, the next one is an eighth of a turn"))


def test_a_count_its_reading_left_unused_goes_where_the_words_say_it():
    (three,) = unread_counts((TURN_LEFT,), "left 3")
    assert three.said == "3" and with_count((TURN_LEFT,), "left 3", three) == ((TURN_LEFT, _walk(3)), True)
    assert unread_counts((TURN_LEFT, _walk(3)), "left 3") == []
    slight = Clause.of(Op.TURN, eighths=1)
    text = "advance 28 cm and left 45"
    (walk,) = unread_counts((slight,), text)
    # Said before the turn: the walk goes first, so the Driver cannot do the turn alone first.
    assert walk.said == "28 cm" and with_count((slight,), text, walk) == ((_walk(4), slight), False)


def test_a_turn_sized_in_degrees_or_clicks_is_that_size():
    """From a browser play: "turn left 45, forward 5" was a quarter turn, and "turn left one click,
    go forward 4. then turn right two clicks ..." a quarter turn, a step and two walks."""
    reader = Understanding.trained()
    slight_left, right = Clause.of(Op.TURN, eighths=1), Clause.of(Op.TURN, eighths=-2)
    assert reader.program("turn left 45, forward 5").meaning == (slight_left, _walk(5))
    assert reader.program("turn 90 degrees to the right and go 3 steps").meaning == (right, _walk(3))
    said = "ok got you. turn left one click, go forward 4. then turn right two clicks and go straight like 10"
    assert reader.program(said).meaning[:3] == (slight_left, _walk(4), right)


@pytest.mark.parametrize(
    "said",
    [
        # The ninth play: each was carried out as "forward 10 steps" into a wall, then the turn
        "that was more than 10 steps i think! ok, turn left a quarter turn",
        "no, I didn't ask for 10 more steps, i was just commenting. turn left first (quarter turn)",
        "ok you went a bit far but fine. turn left a quarter turn",
        # ... and a guess of where the Driver is, carried out as a walk to the wall
        "ok i'm guessing you're at the bottom of the map in a little white corner. turn left a quarter turn",
    ],
)
def test_words_about_what_was_done_or_where_the_driver_is_move_nothing(said):
    reader = Understanding.trained()
    before = ("d", "white wall close ahead, green wall far ahead, yellow wall far ahead")
    assert reader.program(said, before).meaning == (Clause.of(Op.TURN, eighths=2),), said


@pytest.mark.parametrize(
    "said, moves",
    [
        # The ninth play: a walk to the jar and on to the wall, and no claim until the person typed
        # the button's label
        ("great!! if the jar is right in front of you, go up to it and press the found button", [TO_THE_JAR]),
        ("click i found the target", []),
        ("go forward and press found", [Clause.of(Op.FORWARD, steps=None, until=None)]),
    ],
)
def test_told_to_press_its_found_button_the_driver_claims_after_the_moves(said, moves):
    before = ("d", "i am at a jar of blocks, i do not see a red wall ahead. which way now?")
    assert Understanding.trained().program(said, before).meaning == (*moves, Clause.of(Op.STOP, claim=True)), said


def test_a_goodbye_and_the_next_target_named_move_nothing_of_their_own():
    """ "ok we're out of time, stopping here. thanks" had the agent turn around and drive to a wall;
    "next is the mug" was a walk to the mug before the turn around that followed it."""
    reader = Understanding.trained()
    moves = (Op.TURN, Op.FORWARD, Op.BACK, Op.FOLLOW, Op.OPENING)
    assert not [c for c in reader.program("ok we're out of time, stopping here. thanks").meaning if c.op in moves]
    said = "nice one. next is the mug, long way. turn around and go straight until the green wall on your left ends"
    assert reader.program(said).meaning == (
        Clause.of(Op.TURN, eighths=4),
        Clause.of(Op.FORWARD, steps=None, until="green"),
    )

"""The dialog Driver: it reaches a target guided by the oracle Commander on a bundled maze, holds
still while being localized, and takes percepts only (no pose, map or graph)."""

import inspect
import re

import numpy as np
import pytest

from sim.agents.dialog_driver import DialogDriver
from sim.agents.episode import run
from sim.agents.oracle_commander import OracleCommander
from sim.core.dynamics import Action, Pose
from sim.core.labels import OBJECT_LABELS, Label
from sim.core.maze import Maze
from sim.core.navgraph import NavGraph
from sim.core.observations import RayTable
from sim.language import instructions as ins
from sim.language.describe import CENTRE_RAYS, near, seen
from sim.language.driver_personas import DriverPersona
from sim.language.driver_phrasing import PersonaDriverPhrasing
from sim.language.meaning import Clause, Op
from sim.language.phrases import Phrasing
from sim.language.understanding import instructions
from sim.tasks.library import BUNDLED_DIR
from sim.trial.agent import SeatInfo
from sim.trial.commands import Claim, RequestMove, Say
from sim.trial.percepts import Heard, Judged, Moved, Percept, PhaseBegan, Saw
from sim.trial.vocabulary import Move, Outcome, Phase, Role

BUNDLED = BUNDLED_DIR / "gen-000"


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    cache = tmp_path_factory.mktemp("cache")
    maze = Maze.from_dir(BUNDLED, cache_dir=cache)
    graph = NavGraph.build(maze, "benchmark", cache_dir=cache)
    return maze, graph, RayTable.build(maze, graph, cache_dir=cache)


def _far_start(graph, target):
    """A node about a metre of path from the target, facing away (heading 4)."""
    goal = graph.nearest_node(*target)
    dist = graph.dist[:, goal]
    reachable = np.flatnonzero(np.isfinite(dist) & (dist > 0.9))
    return Pose(int(reachable[np.argmin(dist[reachable])]), 4)


@pytest.mark.parametrize("phrasing", list(Phrasing))
def test_the_oracle_commander_guides_it_to_the_first_target(world, phrasing):
    maze, graph, rays = world
    target = ("jar", tuple(maze.objects["jar"]))
    commander = OracleCommander(graph, rays, [target], phrasing)
    result = run(DialogDriver(0), commander, _far_start(graph, target[1]), Phase.NAVIGATING, max_moves=300)
    assert result.success, result.dialog
    assert result.claims == 1 and result.moves <= 2 * result.shortest
    assert result.dialog[-1] == ("navigator", "i think i found the jar of blocks")


def test_its_inputs_are_percepts_only():
    # Its settings (its chance choices, saying a long plan back to a person, how it reads, how it
    # words what it says) are no percepts.
    assert list(inspect.signature(DialogDriver).parameters) == ["seed", "read_back", "understanding", "phrasing"]
    assert list(inspect.signature(DialogDriver.perceive).parameters) == ["self", "percept"]
    assert inspect.signature(DialogDriver.perceive).parameters["percept"].annotation in ("Percept", Percept)


def _rays(world, pose):
    _, _, rays = world
    return rays.observation(*pose)


def test_while_localized_it_answers_and_turns_in_place_but_does_not_drive_off(world):
    driver = DialogDriver(0)
    driver.reset(SeatInfo(Role.DRIVER, 3))
    assert driver.perceive(PhaseBegan(Phase.LOCALIZING, None, 3)) == []
    pose = Pose(100, 0)
    assert driver.perceive(Saw(0, _rays(world, pose))) == []
    answer = driver.perceive(Heard(Role.COMMANDER, "what do you see?"))
    assert len(answer) == 1 and isinstance(answer[0], Say) and "ahead" in answer[0].text
    turns = driver.perceive(Heard(Role.COMMANDER, "go forward 3 steps"))
    assert not any(isinstance(t, RequestMove) for t in turns) and "stay here" in turns[0].text
    # Asked what is behind it, it turns on the spot (never forward) and answers once it has looked.
    turns = driver.perceive(Heard(Role.COMMANDER, "what is behind you?"))
    heading, said = 0, []
    for _ in range(12):
        assert turns and isinstance(turns[0], RequestMove) and turns[0].move != Move.FORWARD
        heading = (heading + (1 if turns[0].move == Move.LEFT else -1)) % 8
        assert driver.perceive(Moved(turns[0].move, Outcome.OK)) == []
        turns = driver.perceive(Saw(1, _rays(world, Pose(100, heading))))
        said = [t for t in turns if isinstance(t, Say)]
        if said:
            break
    assert said and "behind me" in said[0].text and heading == 0


def test_while_localized_told_to_turn_and_say_what_is_ahead_it_turns_and_describes_the_new_view(world):
    """A person's "please turn to your left a quarter turn and tell me what is in front of you then"
    got the same description again and no turn: the rules' reading (a question about its left)
    had replaced the reader's turn."""
    driver = DialogDriver(0)
    driver.reset(SeatInfo(Role.DRIVER, 3))
    driver.perceive(PhaseBegan(Phase.LOCALIZING, None, 3))
    driver.perceive(Saw(0, _rays(world, Pose(100, 0))))
    driver.perceive(Heard(Role.COMMANDER, "what do you see?"))
    said_text = "ok. please turn to your left a quarter turn and tell me what is in front of you then"
    turns, heading, said = driver.perceive(Heard(Role.COMMANDER, said_text)), 0, []
    for _ in range(12):
        if not turns or not isinstance(turns[0], RequestMove):
            break
        assert turns[0].move == Move.LEFT, turns
        heading += 1
        driver.perceive(Moved(turns[0].move, Outcome.OK))
        turns = driver.perceive(Saw(heading, _rays(world, Pose(100, heading))))
        said = [t for t in turns if isinstance(t, Say)]
        if said:
            break
    assert heading == 2 and said, (heading, turns)
    assert "ahead" in said[0].text and "stay here" not in said[0].text, said


def test_told_to_turn_its_back_to_a_wall_it_turns_until_it_faces_it_then_around(world):
    """ "turn so the green wall is behind you and go straight" was carried out as a walk, no turn."""
    driver = DialogDriver(0)
    driver.reset(SeatInfo(Role.DRIVER, 3))
    driver.perceive(PhaseBegan(Phase.NAVIGATING, 0, 3))
    node = 100
    ahead = {h: {s.label for s in seen(_rays(world, Pose(node, h)))} for h in range(8)}
    label = next(
        lab
        for lab in (Label.RED, Label.BLUE, Label.GREEN, Label.YELLOW, Label.WHITE)
        if lab not in ahead[0] and any(lab in ahead[h] for h in range(1, 8))
    )
    driver.perceive(Saw(0, _rays(world, Pose(node, 0))))
    turns, heading = driver.perceive(Heard(Role.COMMANDER, f"turn so the {label.word} wall is behind you")), 0
    for _ in range(16):
        moves = [t for t in turns if isinstance(t, RequestMove)]
        if not moves:
            break
        assert moves[0].move != Move.FORWARD, turns
        heading = (heading + (1 if moves[0].move == Move.LEFT else -1)) % 8
        driver.perceive(Moved(moves[0].move, Outcome.OK))
        turns = driver.perceive(Saw(1, _rays(world, Pose(node, heading))))
    assert label in ahead[(heading + 4) % 8] and label not in ahead[heading], (label, heading, turns)


def _free_run(graph, pose: Pose) -> int:
    """The forward moves free from `pose` before a wall bars the way."""
    node, steps = pose.node, 0
    while (node := int(graph.forward[node, pose.heading])) >= 0 and steps < 100:
        steps += 1
    return steps


def _squarely_at_a_wall(view) -> bool:
    depth, labels = view.depth[CENTRE_RAYS], view.labels[CENTRE_RAYS]
    return float(np.ptp(depth)) <= 0.05 and not set(labels.tolist()) & {int(label) for label in OBJECT_LABELS}


@pytest.mark.parametrize(
    "question", ["how many steps until the wall in front of you?", "how far away is the white wall in front of you?"]
)
def test_asked_how_far_the_wall_ahead_is_it_says_in_steps(world, question):
    """A person commanding it asked "how many steps until the wall in front of you?" and got its view
    again, never a count."""
    _, graph, _ = world
    poses = [  # facing a wall squarely, not a landmark (this graph does not stop at them)
        Pose(n, h)
        for n in range(0, graph.n, 11)
        for h in (0, 2, 4, 6)
        if 2 <= _free_run(graph, Pose(n, h)) <= 12 and _squarely_at_a_wall(_rays(world, Pose(n, h)))
    ]
    assert len(poses) >= 5
    for pose in poses[:5]:
        driver = DialogDriver(0)
        driver.reset(SeatInfo(Role.DRIVER, 3))
        driver.perceive(PhaseBegan(Phase.NAVIGATING, 0, 3))
        driver.perceive(Saw(0, _rays(world, pose)))
        (answer,) = driver.perceive(Heard(Role.COMMANDER, question))
        steps = int(re.search(r"ahead is about (\d+) steps? away", answer.text).group(1))
        assert abs(steps - _free_run(graph, pose)) <= 1, (pose, answer.text, _free_run(graph, pose))


def test_asked_before_its_first_frame_it_answers_once_the_frame_comes(world):
    # On a rover the Commander can speak before the Driver's camera has sent a frame.
    driver = DialogDriver(0)
    driver.reset(SeatInfo(Role.DRIVER, 3))
    driver.perceive(PhaseBegan(Phase.LOCALIZING, None, 3))
    assert driver.perceive(Heard(Role.COMMANDER, "what do you see?")) == []
    (answer,) = driver.perceive(Saw(0, _rays(world, Pose(100, 0))))
    assert isinstance(answer, Say) and "ahead" in answer.text


def test_while_being_found_a_long_polite_request_to_look_is_answered_by_looking(world):
    """A person's first message was answered "no, no yellow wall ahead": the reader read a question
    about a yellow wall nobody named into it."""
    driver = DialogDriver(0)
    driver.reset(SeatInfo(Role.DRIVER, 3))
    driver.perceive(PhaseBegan(Phase.LOCALIZING, None, 3))
    node, heading = 100, 0
    driver.perceive(Saw(0, _rays(world, Pose(node, heading))))
    turns = driver.perceive(
        Heard(
            Role.COMMANDER,
            "Hello there, nice to meet you! I'm looking at the map now but I can't see where you are yet. Could "
            "you please tell me what you can see in front of you? And maybe turn around slowly and tell me "
            "what colours the walls are on each side?",
        )
    )
    for _ in range(12):
        if not turns or not isinstance(turns[0], RequestMove):
            break
        assert turns[0].move != Move.FORWARD
        heading = (heading + (1 if turns[0].move == Move.LEFT else -1)) % 8
        driver.perceive(Moved(turns[0].move, Outcome.OK))
        turns = driver.perceive(Saw(1, _rays(world, Pose(node, heading))))
    (said,) = [t.text for t in turns if isinstance(t, Say)]
    assert "behind me" in said and "on my left" in said and "no, no" not in said, said


def _carry_out(driver, world, pose, text):
    """The Commander says `text`; the Driver's moves are stepped on the graph until it speaks."""
    _, graph, _ = world
    turns = driver.perceive(Heard(Role.COMMANDER, text))
    for _ in range(200):
        said = [t.text for t in turns if isinstance(t, Say)]
        if said:
            return pose, said
        (move,) = [t for t in turns if isinstance(t, RequestMove)]
        action = {Move.FORWARD: Action.FORWARD, Move.LEFT: Action.LEFT, Move.RIGHT: Action.RIGHT}[move.move]
        pose, collided = graph.moves.step(pose, action)
        result = Outcome.COLLISION if collided else Outcome.OK
        turns = driver.perceive(Moved(move.move, result)) + driver.perceive(Saw(0, _rays(world, pose)))
    raise AssertionError("the Driver never spoke")


def _ahead(graph, node, heading, steps):
    """The node `steps` forward moves from `node` along `heading`."""
    for _ in range(steps):
        node = int(graph.forward[node, heading])
    return node


def _room_for(graph, ahead, left, heading=2):
    """A pose heading 0 with `ahead` free moves along +x, then `left` along `heading` (+y)."""
    for node in range(graph.n):
        n = node
        for k in range(ahead + left):
            n = int(graph.forward[n, 0 if k < ahead else heading])
            if n < 0:
                break
        else:
            return Pose(node, 0)
    raise AssertionError("no open stretch in the maze")


def test_it_goes_back_to_where_it_started_by_its_own_odometry(world):
    _, graph, _ = world
    start = _room_for(graph, 3, 2)
    driver = _navigating(world, start)
    pose, said = _carry_out(driver, world, start, "go forward 3 steps, then turn left")
    pose, said = _carry_out(driver, world, pose, "go forward 2 steps")
    assert pose.node != start.node and said[0].startswith("ok")
    pose, said = _carry_out(driver, world, pose, "go back to where you started")
    assert pose.node == start.node and "back where i started" in said[0], said
    corner = start.node
    for _ in range(3):
        corner = int(graph.forward[corner, 0])
    pose, said = _carry_out(driver, world, pose, "now go back to where you turned left first")
    assert pose.node == corner and "back where i turned" in said[0], said


def test_it_asks_when_it_bumps_is_rejected_or_does_not_understand(world):
    _, graph, _ = world
    start = _room_for(graph, 3, 0)
    driver = DialogDriver(0)
    driver.reset(SeatInfo(Role.DRIVER, 3))
    driver.perceive(PhaseBegan(Phase.NAVIGATING, 0, 3))
    driver.perceive(Saw(0, _rays(world, start)))
    (said,) = driver.perceive(Heard(Role.COMMANDER, "blorp the snark"))
    assert isinstance(said, Say) and "did not understand 'blorp the snark'" in said.text  # says what it missed
    (move,) = driver.perceive(Heard(Role.COMMANDER, "go forward 3 steps"))
    assert move == RequestMove(Move.FORWARD)
    (said,) = driver.perceive(Moved(Move.FORWARD, Outcome.COLLISION))
    assert said == Say("i hit a wall, which way now?")
    assert driver.perceive(Saw(1, _rays(world, start))) == []  # the rest of the walk is dropped
    turns = driver.perceive(Heard(Role.COMMANDER, "stop there and take a picture"))
    assert turns[-1] == Claim()
    (said,) = driver.perceive(Judged(confirmed=False, target_index=0))
    assert said.text.endswith("where should i go?")


def test_rejected_where_it_sees_the_target_it_goes_on_up_to_it(world):
    """Its claim rejected with the jar in reach (a Commander's reading of the frame can be stricter
    than its own), told again to go up to the jar, it goes closer and claims again: stopping where
    it stands, it answered "ok, at the jar" to the same instruction until the message cap."""
    _, graph, _ = world
    poses = [Pose(n, h) for n in range(graph.n) for h in range(8)]
    start = next(
        p
        for p in poses
        if near(_rays(world, p), Label.JAR)
        and not graph.moves.step(p, Action.FORWARD)[1]
        and near(_rays(world, graph.moves.step(p, Action.FORWARD)[0]), Label.JAR)
    )
    driver = DialogDriver(0)
    driver.reset(SeatInfo(Role.DRIVER, 3))
    driver.perceive(PhaseBegan(Phase.NAVIGATING, 0, 3))
    driver.perceive(Saw(0, _rays(world, start)))
    assert driver.perceive(Heard(Role.COMMANDER, "now find the jar of blocks"))[-1] == Claim()
    driver.perceive(Judged(confirmed=False, target_index=0))
    (move,) = driver.perceive(Heard(Role.COMMANDER, "go forward until you see the jar of blocks"))
    assert move == RequestMove(Move.FORWARD)
    driver.perceive(Moved(Move.FORWARD, Outcome.OK))
    turns = driver.perceive(Saw(1, _rays(world, graph.moves.step(start, Action.FORWARD)[0])))
    assert turns[-1] == Claim()


@pytest.mark.parametrize("persona", [None, DriverPersona.TERSE])
def test_told_to_walk_into_a_wall_it_stops_says_so_and_counts_it(world, persona):
    """It looks before each step: told five steps with a wall after one, it drives one and stops,
    says how far it got (in the persona's words where it has one) and counts a move refused for a
    wall, what self-play's bumps per instruction count."""
    _, graph, _ = world
    pose = next(
        Pose(n, 0) for n in range(graph.n) if graph.forward[n, 0] >= 0 and graph.forward[graph.forward[n, 0], 0] < 0
    )
    phrasing = PersonaDriverPhrasing(persona) if persona is not None else None
    driver = DialogDriver(0, phrasing=phrasing)
    driver.reset(SeatInfo(Role.DRIVER, 3))
    driver.perceive(PhaseBegan(Phase.NAVIGATING, None, 3))
    driver.perceive(Saw(0, _rays(world, pose)))
    end, said = _carry_out(driver, world, pose, "go forward 5 steps")
    assert end.node == graph.forward[pose.node, 0] and driver.refused_for_walls == 1
    if persona is None:
        assert said[0].startswith("i can only go 1 steps")
    else:
        assert re.match(r"(wall after|blocked at|stuck after|hit wall,) 1\b", said[0]), said


def test_told_it_is_at_the_target_out_of_view_it_looks_around_for_it_and_claims(world):
    """ "you're at the jar" with the jar behind it: it turns until the jar is in view and claims,
    rather than saying nothing or claiming blind."""
    _, graph, _ = world
    start = next(
        Pose(n, h)
        for n in range(graph.n)
        for h in range(8)
        if near(_rays(world, Pose(n, (h + 4) % 8)), Label.JAR)
        and not any(s == Label.JAR for s in _rays(world, Pose(n, h)).labels[_rays(world, Pose(n, h)).valid])
    )
    driver = DialogDriver(0)
    driver.reset(SeatInfo(Role.DRIVER, 3))
    driver.perceive(PhaseBegan(Phase.NAVIGATING, 0, 3))
    driver.perceive(Saw(0, _rays(world, start)))
    turns = driver.perceive(Heard(Role.COMMANDER, "you're at the jar now"))
    pose = start
    for _ in range(8):
        assert turns and isinstance(turns[0], RequestMove) and turns[0].move == Move.LEFT, turns
        pose, _ = graph.moves.step(pose, Action.LEFT)
        turns = driver.perceive(Moved(Move.LEFT, Outcome.OK)) + driver.perceive(Saw(0, _rays(world, pose)))
        if any(isinstance(t, Claim) for t in turns):
            break
    assert any(isinstance(t, Claim) for t in turns) and near(_rays(world, pose), Label.JAR)


def test_told_again_after_looking_all_around_in_vain_it_trusts_the_map_and_claims(world):
    _, graph, _ = world
    start = next(
        Pose(n, 0)
        for n in range(graph.n)
        if not any(Label.JAR in _rays(world, Pose(n, h)).labels[_rays(world, Pose(n, h)).valid] for h in range(8))
    )
    driver = DialogDriver(0)
    driver.reset(SeatInfo(Role.DRIVER, 3))
    driver.perceive(PhaseBegan(Phase.NAVIGATING, 0, 3))
    driver.perceive(Saw(0, _rays(world, start)))
    pose, said = _carry_out(driver, world, start, "you're at the jar")
    assert pose.node == start.node and "do not see the jar of blocks" in said[0], said
    turns = driver.perceive(Heard(Role.COMMANDER, "you are at the jar"))
    assert any(isinstance(t, Claim) for t in turns), turns


@pytest.mark.parametrize(
    "text", ["you are right by it", "got it, you are right by it now", "got it, you found it, you are right by it"]
)
def test_told_it_is_right_by_the_target_it_claims_and_does_not_turn_right(world, text):
    _, graph, _ = world
    at_jar = next(Pose(n, h) for n in range(graph.n) for h in range(8) if near(_rays(world, Pose(n, h)), Label.JAR))
    driver = DialogDriver(0)
    driver.reset(SeatInfo(Role.DRIVER, 3))
    driver.perceive(PhaseBegan(Phase.NAVIGATING, 0, 3))
    driver.perceive(Heard(Role.COMMANDER, "now find the jar"))
    turns = driver.perceive(Saw(0, _rays(world, at_jar)))
    turns += driver.perceive(Heard(Role.COMMANDER, text))
    assert any(isinstance(t, Claim) for t in turns), turns
    assert not any(isinstance(t, RequestMove) for t in turns), turns


def test_told_no_with_the_other_way_after_it_asked_it_takes_the_correction(world):
    _, graph, _ = world
    start = _room_for(graph, 2, 0)
    driver = _navigating(world, start)
    (asked,) = driver.perceive(Heard(Role.COMMANDER, "go leftish"))  # words it is unsure of
    assert isinstance(asked, Say) and "do you mean" in asked.text, asked
    turns = driver.perceive(Heard(Role.COMMANDER, "no right"))
    assert turns and isinstance(turns[0], RequestMove) and turns[0].move == Move.RIGHT, turns


def _navigating(world, pose, read_back=False):
    driver = DialogDriver(0, read_back=read_back)
    driver.reset(SeatInfo(Role.DRIVER, 3))
    driver.perceive(PhaseBegan(Phase.NAVIGATING, 0, 3))
    driver.perceive(Saw(0, _rays(world, pose)))
    return driver


def _sees(world, pose, label):
    return any(s.label == label for s in seen(_rays(world, pose)))


def test_told_to_turn_until_it_sees_the_mug_it_turns_until_then_and_does_not_walk(world):
    """The reader reads "turn left until you see the coffee mug" as a turn and a walk to the mug:
    the Driver turned 90 degrees and drove to the mug, a walk nobody asked for."""
    _, graph, _ = world
    start, heading = next(
        (Pose(n, 0), h)
        for n in range(graph.n)
        for h in (2, 3)
        if _sees(world, Pose(n, h), Label.MUG) and not any(_sees(world, Pose(n, k), Label.MUG) for k in range(h))
    )
    driver = _navigating(world, start)
    pose, said = _carry_out(driver, world, start, "turn left until you see the coffee mug")
    assert pose == Pose(start.node, heading), said
    assert said[0].startswith(f"ok, turned left {45 * heading} degrees,") and "forward" not in said[0], said


def test_its_report_and_read_back_say_how_far_it_turned(world):
    _, graph, _ = world
    start = _room_for(graph, 0, 2)
    driver = _navigating(world, start, read_back=True)
    turns = driver.perceive(Heard(Role.COMMANDER, "turn left 90, then go forward 2 steps"))
    assert turns[0] == Say("ok: turning left 90 degrees, then forward 2 steps"), turns
    driver = _navigating(world, start)
    _, said = _carry_out(driver, world, start, "turn right 45 degrees")
    assert said[0].startswith("ok, turned right 45 degrees,"), said
    _, said = _carry_out(driver, world, start, "turn around")
    assert said[0].startswith("ok, turned around,"), said


@pytest.mark.parametrize(("text", "heading"), [("left 3", 2), ("right 3", 6), ("go right 2 steps", 6)])
def test_told_a_side_and_a_count_it_asks_whether_to_turn_that_way_and_walk_the_count(world, text, heading):
    """A person's terse "left 3": the reader read it as the turn alone, and "right 3" as the walk
    alone, straight ahead, with an "ok". "left 1 then fwd 2" meant a turn counted, so it asks."""
    _, graph, _ = world
    steps = int(next(w for w in text.split() if w.isdigit()))
    start = _room_for(graph, 0, steps, heading)
    driver = _navigating(world, start)
    (asked,) = driver.perceive(Heard(Role.COMMANDER, text))
    side = "left" if heading == 2 else "right"
    assert asked == Say(
        f"i am not sure i got '{text}'. do you mean: turning {side} 90 degrees, then forward {steps} steps?"
    )
    pose, said = _carry_out(driver, world, start, "yes")
    end = _ahead(graph, start.node, heading, steps)
    assert pose == Pose(end, heading) and said[0].startswith(f"ok, went {steps} steps"), said


def test_a_turn_its_reading_dropped_is_asked_about_with_the_words_read_clause_by_clause(world):
    """A person's "right, fwd 2" was read as the walk alone: the Driver went straight and said "ok"."""
    _, graph, _ = world
    start = _room_for(graph, 0, 2, 6)
    driver = _navigating(world, start)
    (asked,) = driver.perceive(Heard(Role.COMMANDER, "right, fwd 2"))
    assert asked == Say(
        "i am not sure i got 'right, fwd 2'. do you mean: turning right 90 degrees, then forward 2 steps?"
    )
    pose, said = _carry_out(driver, world, start, "yes")
    end = _ahead(graph, start.node, 6, 2)
    assert pose == Pose(end, 6) and said[0].startswith("ok, went 2 steps"), said


@pytest.mark.parametrize("text", ["what do u see", "thats right, go forward 1", "right now go forward 1"])
def test_u_and_right_that_mean_you_and_directly_move_nothing_and_turn_nothing(world, text):
    _, graph, _ = world
    start = _room_for(graph, 1, 0)
    pose, said = _carry_out(_navigating(world, start), world, start, text)
    assert pose.heading == start.heading and "turn" not in said[0], said


def test_a_question_is_answered_with_no_move_it_was_not_asked_for(world):
    """ "can you see the mug or the jar or the paddle anywhere? maybe look around a bit" was read
    as "the mug should be on your left" and a u-turn: the Driver turned round and said "ok"."""
    _, graph, _ = world
    start = _room_for(graph, 1, 0)
    driver = _navigating(world, start)
    turns = driver.perceive(Heard(Role.COMMANDER, "can you see the mug or the jar or the paddle anywhere?"))
    assert not [t for t in turns if isinstance(t, RequestMove)] and [t for t in turns if isinstance(t, Say)], turns


def test_asked_if_it_sees_an_object_anywhere_it_answers_from_every_side_it_has_looked_at(world):
    """A person's "can you see the mug anywhere?" got "no" from the view ahead, with the mug on the
    agent's left where it had just looked; not seen, it offers to look around and does when told yes."""
    _, graph, _ = world
    start = next(
        Pose(n, 0)
        for n in range(graph.n)
        if _sees(world, Pose(n, 2), Label.MUG) and not any(_sees(world, Pose(n, h), Label.MUG) for h in (0, 1))
    )
    driver = _navigating(world, start)
    pose, said = _carry_out(driver, world, start, "what is on your left?")
    assert pose == start, said
    _, said = _carry_out(driver, world, pose, "can you see the mug anywhere?")
    assert len(said) == 1 and said[0].startswith("yes") and said[0].endswith("mug on my left"), said

    elsewhere = next(
        Pose(n, 0)
        for n in range(graph.n)
        if not any(_sees(world, Pose(n, h), Label.MUG) for h in (0, 1, 7)) and _sees(world, Pose(n, 4), Label.MUG)
    )
    driver = _navigating(world, elsewhere)
    turns = driver.perceive(Heard(Role.COMMANDER, "can you see the mug anywhere?"))
    assert not any(isinstance(t, RequestMove) for t in turns), "no scored move unasked"
    (answer,) = [t.text for t in turns if isinstance(t, Say)]
    assert answer.startswith("no, no coffee mug ahead") and answer.endswith("should i look around?"), answer
    pose, said = _carry_out(driver, world, elsewhere, "yes")
    assert pose.node == elsewhere.node and "mug behind me" in said[0], said


@pytest.mark.parametrize(
    ("text", "steps", "eighths"),
    [
        ("press left twice", 0, 2),
        ("hit the right button once", 0, -1),
        ("click forward 2 times", 2, 0),
        ("press forward", 1, 0),
        ("tap forward twice then left once", 2, 1),
    ],
)
def test_button_presses_counted_by_a_person_are_one_move_each(world, text, steps, eighths):
    """A person who knows the Driver's buttons counts presses: "press left twice" was two quarter
    turns, "press forward" a walk to the wall and "click forward 2 times" not understood."""
    _, graph, _ = world
    start = _room_for(graph, 3, 0)
    pose, said = _carry_out(_navigating(world, start), world, start, text)
    assert pose == Pose(_ahead(graph, start.node, 0, steps), eighths % 8), said
    assert said[0].startswith("ok"), said


def test_a_long_message_it_is_unsure_of_is_not_said_back_whole(world):
    """A person's four-sentence messages came back whole inside "i am not sure i got '...'"."""
    _, graph, _ = world
    start = _room_for(graph, 1, 0)
    turns = _navigating(world, start).perceive(
        Heard(
            Role.COMMANDER,
            "Oops, I think I sent you too far, sorry! The paddle is on the other side of that white wall on "
            "your left. Please turn around and go back about 8 steps.",
        )
    )
    (said,) = [t.text for t in turns if isinstance(t, Say)]
    assert said.startswith("i am not sure i got all of that. do you mean: ") and "Oops" not in said, said


@pytest.mark.parametrize("text", ["say found", "thats the target", "this is it", "press found"])
def test_told_in_other_words_that_it_is_there_it_claims(world, text):
    _, graph, _ = world
    start = _room_for(graph, 1, 0)
    _, said = _carry_out(_navigating(world, start), world, start, text)
    assert said[0].startswith("i think i found"), said


def test_thanks_is_chat_not_a_stop_it_did_not_make(world):
    _, graph, _ = world
    start = _room_for(graph, 1, 0)
    assert _navigating(world, start).perceive(Heard(Role.COMMANDER, "thanks")) == []


def test_told_left_then_3_it_turns_says_it_did_not_get_the_3_and_walks_it_when_told_yes(world):
    """ "left, then 3" read as a turn alone: the Driver turned and said "ok", the 3 dropped in silence."""
    _, graph, _ = world
    start = _room_for(graph, 0, 3)
    driver = _navigating(world, start)
    pose, said = _carry_out(driver, world, start, "left, then 3")
    assert pose == Pose(start.node, 2) and said[0].endswith("i did not get '3' - forward 3 steps?"), said
    pose, said = _carry_out(driver, world, pose, "yes")
    end = _ahead(graph, start.node, 2, 3)
    assert pose == Pose(end, 2) and said[0].startswith("ok, went 3 steps"), said


@pytest.mark.parametrize("yes", ["yes", "yep", "sure thing", "y"])
def test_a_count_said_before_the_turn_it_did_get_is_asked_about_before_it_moves(world, yes):
    """Doing the turn it understood first would put the walk it did not get in the wrong place; a
    person's "yep" to the question is a yes."""
    _, graph, _ = world
    start = _room_for(graph, 4, 0)
    driver = _navigating(world, start)
    (asked,) = driver.perceive(Heard(Role.COMMANDER, "3 then left"))  # the reader reads a left turn
    assert asked == Say("i am not sure i got '3'. do you mean: forward 3 steps, then turning left 90 degrees?")
    pose, said = _carry_out(driver, world, start, yes)
    ahead = start.node
    for _ in range(3):
        ahead = int(graph.forward[ahead, 0])
    assert pose == Pose(ahead, 2) and said[0].startswith("ok, turned left 90 degrees,"), said


@pytest.mark.parametrize(
    "text",
    [
        "go straight ahead like 3 steps and tell me what u see",
        "Great, thank you! Could you please go forward 3 steps and then tell me what you see?",
    ],
)
def test_a_walk_said_with_a_question_is_walked_and_the_view_told_from_where_it_ends(world, text):
    """A person's "go straight ahead like 10 steps and tell me what u see" got the view alone, twice,
    with no word of the walk; polite requests worded as questions got "do you mean: ...?" about one
    time in three."""
    _, graph, _ = world
    start = _room_for(graph, 3, 0)
    driver = _navigating(world, start)
    pose, said = _carry_out(driver, world, start, text)
    assert pose == Pose(_ahead(graph, start.node, 0, 3), 0), said
    assert "ahead" in said[-1] and not any("do you mean" in s for s in said), said


def test_turn_around_and_tell_me_what_you_see_turns_half_way_round_and_tells(world):
    """A person's "Turn around and tell me what you see" made the agent look all around (eight moves)."""
    _, graph, _ = world
    start = _room_for(graph, 1, 0)
    pose, said = _carry_out(_navigating(world, start), world, start, "Turn around and tell me what you see.")
    assert pose == Pose(start.node, 4) and "ahead" in said[-1] and not any("do you mean" in s for s in said), said


@pytest.mark.parametrize(
    "text",
    ["turn all the way around slowly and tell me every color you see", "spin around 360 and tell me what you see"],
)
def test_a_whole_circle_asked_for_is_a_look_all_around(world, text):
    """A person's "turn all the way around slowly and tell me every color you see" got a half turn
    and one view; "spin around 360 ..." a half turn and "forward 360 steps?"."""
    start = Pose(100, 0)
    pose, said = _carry_out(_navigating(world, start), world, start, text)
    assert pose == start and "behind me" in said[0] and "360" not in " ".join(said), said


def test_another_object_said_to_be_in_view_is_answered_not_sought_or_claimed(world):
    """A person placing the robot by a landmark ("i think you are facing the red wall near the mug",
    "you are next to the jar") made the agent look all around for the mug, and claim the jar when
    the mug was next: another object than the leg's target is answered from the view, no move."""
    _, graph, _ = world
    pose = next(
        Pose(n, h)
        for n in range(graph.n)
        for h in range(8)
        if near(_rays(world, Pose(n, h)), Label.JAR) and not _sees(world, Pose(n, h), Label.MUG)
    )
    driver = DialogDriver(0)
    driver.reset(SeatInfo(Role.DRIVER, 3))
    driver.perceive(PhaseBegan(Phase.LOCALIZING, None, 3))
    driver.perceive(Saw(0, _rays(world, pose)))
    driver.perceive(Heard(Role.COMMANDER, "your target is the coffee mug"))
    driver.perceive(PhaseBegan(Phase.NAVIGATING, 0, 3))
    for text in ("you are next to the jar", "i think you are facing the jar", "the jar should be ahead of you"):
        turns = driver.perceive(Heard(Role.COMMANDER, text))
        assert not any(isinstance(t, RequestMove | Claim) for t in turns), (text, turns)
        (answer,) = [t.text for t in turns if isinstance(t, Say)]
        assert "jar" in answer and "found" not in answer, (text, answer)
    # Named to find, it is the target again.
    turns = driver.perceive(Heard(Role.COMMANDER, "sorry, i meant find the jar"))
    assert any(isinstance(t, Claim) for t in turns), turns


def test_a_walk_to_an_object_stopped_by_a_wall_short_of_it_is_not_reported_done(world):
    """Told to go up to the jar facing a wall, it had answered "ok, at the white wall" with no step made."""
    _, graph, _ = world
    pose = next(
        Pose(n, h)
        for n in range(graph.n)
        for h in range(8)
        if graph.forward[n, h] < 0 and not _sees(world, Pose(n, h), Label.JAR)
    )
    driver = _navigating(world, pose)
    turns = driver.perceive(Heard(Role.COMMANDER, "go forward until you reach the jar"))
    assert not any(isinstance(t, RequestMove) for t in turns), turns
    (said,) = [t.text for t in turns if isinstance(t, Say)]
    assert not said.startswith("ok") and "do not see a jar" in said, said


def _at_object(world) -> Pose:
    _, graph, _ = world
    return next(Pose(n, h) for n in range(graph.n) for h in range(8) if near(_rays(world, Pose(n, h)), Label.JAR))


@pytest.mark.parametrize(
    "text",
    [
        "Great, that's it. Tell the system you found it.",
        "press the I found the target button please",
        "you found the target",
    ],
)
def test_at_an_object_told_in_a_persons_words_to_claim_it_claims(world, text):
    """A person commanding said each of these four times at the paddle, and the agent said "ok,
    already at the ping-pong paddle" or asked "do you mean: forward to the wall?"."""
    driver = _navigating(world, _at_object(world))
    turns = driver.perceive(Heard(Role.COMMANDER, text))
    assert any(isinstance(t, Claim) for t in turns), turns
    assert not any(isinstance(t, RequestMove) for t in turns), turns


def test_a_no_that_says_claim_it_is_a_claim(world):
    driver = _navigating(world, _at_object(world))
    (asked,) = driver.perceive(Heard(Role.COMMANDER, "go leftish"))
    assert "do you mean" in asked.text, asked
    turns = driver.perceive(Heard(Role.COMMANDER, "no. you are at the jar. claim it"))
    assert any(isinstance(t, Claim) for t in turns), turns


def test_a_greeting_with_a_question_is_answered_not_called_unclear(world):
    """ "Hello. What do you see in front of you? Describe the walls and any objects please." was
    the first thing a person said to it, and it said it did not understand."""
    _, graph, _ = world
    driver = _navigating(world, _room_for(graph, 2, 0))
    turns = driver.perceive(
        Heard(Role.COMMANDER, "Hello. What do you see in front of you? Describe the walls and any objects please.")
    )
    (said,) = [t.text for t in turns if isinstance(t, Say)]
    assert "did not understand" not in said and "ahead" in said, said
    assert not any(isinstance(t, RequestMove) for t in turns), turns


def test_turn_around_and_go_back_the_way_you_came_turns_around_once():
    program = (
        Clause.of(Op.TURN, eighths=4),
        Clause.of(Op.BACK, place="previous", steps=18),
    )
    assert instructions(program, "turn around and go back the way you came, about 18 steps") == [
        ins.Turn(4),
        ins.Forward(18),
    ]


def test_told_to_go_to_an_object_at_the_edge_of_its_view_it_turns_to_it_first(world):
    """ "Great! Go to the paddle." with the paddle at the edge of its view: it walked straight on
    into the wall beside it, and said it did not see the paddle ahead."""
    _, graph, _ = world

    def off_centre(pose: Pose) -> int:  # the side the jar is on, 0 where it is not off to one side
        view = _rays(world, pose)
        rays = np.flatnonzero(view.valid & (view.labels == Label.JAR))
        if not rays.size or (view.labels[CENTRE_RAYS] == Label.JAR).any():
            return 0
        return 1 if rays.mean() > 6 else -1

    pose = next(Pose(n, h) for n in range(graph.n) for h in range(8) if off_centre(Pose(n, h)))
    driver = _navigating(world, pose)
    (move,) = driver.perceive(Heard(Role.COMMANDER, "go to the jar"))
    assert isinstance(move, RequestMove) and move.move == (Move.LEFT if off_centre(pose) > 0 else Move.RIGHT), move
    _, said = _carry_out(_navigating(world, pose), world, pose, "go up to the jar of blocks")
    assert said and "do not see" not in said[0], said


@pytest.mark.parametrize("text", ["Yes, that is right.", "that is the right way", "correct, that is right"])
def test_agreement_is_neither_a_turn_nor_a_claim(world, text):
    """A person's "Yes, that is right." made the agent turn right 90 degrees, "that is the right
    way" 135."""
    driver = _navigating(world, _at_object(world))
    turns = driver.perceive(Heard(Role.COMMANDER, text))
    assert not any(isinstance(t, RequestMove | Claim) for t in turns), turns


def test_a_confirmed_target_named_again_is_not_claimed_again(world):
    """Right after the jar was confirmed, "great, that's the jar!" made it claim the jar again,
    as the next target."""
    driver = _navigating(world, _at_object(world))
    turns = driver.perceive(Heard(Role.COMMANDER, "now find the jar"))
    assert any(isinstance(t, Claim) for t in turns), turns
    driver.perceive(Judged(True, 0))
    driver.perceive(PhaseBegan(Phase.NAVIGATING, 1, 3))
    turns = driver.perceive(Heard(Role.COMMANDER, "great, you are at the jar of blocks!"))
    assert not any(isinstance(t, Claim | RequestMove) for t in turns), turns

"""The dialog localizer: what it reads in sentences of the train split (every direction word,
negation, relations, shapes, yes / no answers, reported turns), that its belief settles on the
pose a description was written from, and `eval ldh --agent dialog` with its per-turn curve."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from app.cli import root
from sim.core.labels import Label
from sim.core.maze import Maze
from sim.core.navgraph import NavGraph
from sim.core.observations import RayTable
from sim.language.calibration import FITTED, SHARE_EDGES, Evidence, Record, evidence, fit
from sim.language.lexicon import Fact, Source, ViewKind, answer, facts, question, turn_steps
from sim.language.localizer import HUMAN, TUNED, Belief, Scene, Weights
from sim.language.sectors import Sector
from sim.tasks.ldh_eval import MazeContext
from sim.tasks.library import MazeLibrary
from tests.sim.helpers import open_table, wall_at_x

F, L, B, R, ANY = Sector.FRONT, Sector.LEFT, Sector.BEHIND, Sector.RIGHT, Sector.ANY


def seen(facts: list[Fact]) -> set[tuple[tuple[Sector, ...], Label, bool]]:
    """The label and edge facts as (sectors, label, negated); the edge's label is white."""
    return {
        (f.sectors, f.label, f.negated)
        for f in facts
        if f.kind in (ViewKind.LABEL, ViewKind.EDGE) and f.label is not None
    }


def test_every_direction_word_counts():
    # one label, two directions joined by "and": each holds
    assert seen(facts("There are blue walls in front and to my left and the edge of the maze to my right")) == {
        ((F,), Label.BLUE, False),
        ((L,), Label.BLUE, False),
        ((R,), Label.WHITE, False),
    }
    assert seen(facts("white on both sides")) == {((L,), Label.WHITE, False), ((R,), Label.WHITE, False)}
    assert seen(facts("green walls on either side")) == {((L,), Label.GREEN, False), ((R,), Label.GREEN, False)}
    assert seen(facts("white wall to the left and right")) == {
        ((L,), Label.WHITE, False),
        ((R,), Label.WHITE, False),
    }
    # two labels, two directions in one clause: paired in order, not the clause's last direction for both
    assert seen(facts("Brown walls to the left blue to the right")) == {
        ((L,), Label.BROWN, False),
        ((R,), Label.BLUE, False),
    }
    # two directions for one place: either may hold
    assert seen(facts("Red wall is up ahead to the left")) == {((F, L), Label.RED, False)}
    # a label named twice ("white edge") is one mention
    assert len(facts("The white edge wall is ahead")) == 1


def test_labels_listed_before_a_direction_share_it():
    # colours under one noun stand side by side and share the direction named after them
    got = facts("There are yellow walls to my left and red and white walls to my right")
    assert seen(got) == {((L,), Label.YELLOW, False), ((R,), Label.RED, False), ((R,), Label.WHITE, False)}
    assert [(f.label, f.other) for f in got if f.kind == ViewKind.NEXT_TO] == [(Label.RED, Label.WHITE)]
    # separate nouns share the direction too, but are not said to meet
    got = facts("I can see one red wall and two yellow walls far ahead of me")
    assert seen(got) == {((F,), Label.RED, False), ((F,), Label.YELLOW, False)}
    assert {f.distance.value for f in got} == {"far"} and not [f for f in got if f.kind == ViewKind.NEXT_TO]
    # a list of three, with commas or "and"s, shares it to its first colour
    for said in (
        "i see brown, red and yellow walls ahead",
        "brown,red,yellow in front",
        "brown and red and yellow ahead",
    ):
        assert seen(facts(said)) == {((F,), label, False) for label in (Label.BROWN, Label.RED, Label.YELLOW)}, said
    # a clause of its own keeps its own direction
    assert ((ANY,), Label.RED, False) in seen(facts("i see a red wall and there is a blue wall on my left"))
    assert ((ANY,), Label.RED, False) in seen(facts("i see red, then a blue wall on my left"))
    # "between yellow walls": on both sides
    assert seen(facts("I'm in between yellow walls")) == {((L,), Label.YELLOW, False), ((R,), Label.YELLOW, False)}


def test_the_edge_of_the_maze_is_the_tables_border_not_any_white_wall():
    kinds = {
        f.kind: f for f in facts("I'm facing blue walls, with a white wall on my left and the edge of maze on my right")
    }
    assert kinds[ViewKind.EDGE].sectors == (R,) and kinds[ViewKind.EDGE].label == Label.WHITE
    assert ((L,), Label.WHITE, False) in {(f.sectors, f.label, f.negated) for f in facts("white wall to my left")}
    assert facts("the end of the maze which is white")[0].kind == ViewKind.EDGE


def test_near_and_far():
    (near,) = facts("To my immediate left i see a red wall")
    (front,) = facts("I am in front of red walls")  # standing at them, not seeing them ahead
    assert front.distance.value == "near" and facts("in front of me is a red wall")[0].distance.value == "any"
    (far,) = facts("blue far ahead")
    assert (near.sectors, near.label, near.distance.value) == ((L,), Label.RED, "near")
    assert (far.sectors, far.label, far.distance.value) == ((F,), Label.BLUE, "far")


def test_how_far_said_after_the_wall_is_of_that_wall():
    # A part naming only how far says it of the wall before it; "a step or two away" and "not
    # far" are near, "a good way off" far, "a little way off" neither (and no way through).
    def distances(text: str) -> list[tuple[Label | None, str]]:
        return [(f.label, f.distance.value) for f in facts(text)]

    assert distances("white wall straight ahead of me, really close. a red wall to my left") == [
        (Label.WHITE, "near"),
        (Label.RED, "any"),
    ]
    assert distances("a blue wall ahead and it looks right there") == [(Label.BLUE, "near")]
    assert distances("red wall in front, a step or two away") == [(Label.RED, "near")]
    assert distances("maybe a yellow wall ahead? not far") == [(Label.YELLOW, "near")]
    assert distances("a white wall ahead, a good way off") == [(Label.WHITE, "far")]
    assert distances("a green wall in front of me, just a little way off") == [(Label.GREEN, "any")]
    assert distances("a red wall 5 steps away") == [(Label.RED, "far")]


def test_negation():
    got = facts("i dont see a opening with yellow on right and white on left")
    assert ((R,), Label.YELLOW, True) in seen(got)
    assert any(f.kind == ViewKind.CORRIDOR and f.negated for f in got)
    # an answering "no" before a statement negates nothing
    got = facts("no there is a red dead end")
    assert seen(got) == {((ANY,), Label.RED, False)}
    assert [f.kind for f in got if f.kind != ViewKind.LABEL] == [ViewKind.DEAD_END]
    assert seen(facts("no red wall")) == {((ANY,), Label.RED, True)}


def test_a_question_about_what_it_names_states_none_of_it():
    # Sentences of our own, in the kinds the gold guide gives (docs/language_gold.md).
    assert seen(facts("should the red walls be on my left?")) == set()
    assert seen(facts("where is the edge")) == set()
    assert seen(facts("is that the yellow wall? i see a blue wall on my right")) == {((R,), Label.BLUE, False)}
    # A question at a place it names says the place is there; a question's own facts are read for
    # the answer to it.
    assert seen(facts("should i turn right at the white wall?")) == {((ANY,), Label.WHITE, False)}
    assert seen(answer(question("is there a green wall on your left?"), "no")) == {((L,), Label.GREEN, True)}


def test_relations_and_shapes():
    got = facts("a yellow wall directly in front of me and a red wall next to it")
    assert [(f.label, f.other) for f in got if f.kind == ViewKind.NEXT_TO] == [(Label.YELLOW, Label.RED)]
    got = facts("i am now facing the red and yellow corner")
    assert {(f.kind, f.label, f.other) for f in got if f.kind != ViewKind.LABEL} == {
        (ViewKind.NEXT_TO, Label.RED, Label.YELLOW),
        (ViewKind.CORNER, None, None),
    }
    got = facts("I see a gap between a blue and white wall with a brown wall at the end of it")
    assert (ViewKind.NEXT_TO, Label.BLUE, Label.WHITE) in {(f.kind, f.label, f.other) for f in got}
    assert any(f.kind == ViewKind.CORRIDOR for f in got)
    assert ((ANY,), Label.BROWN, False) in seen(got)
    corridor = [
        f for f in facts("my left is a long corridor with a brown wall at the end") if f.kind == ViewKind.CORRIDOR
    ]
    assert [f.sectors for f in corridor] == [(L,)]
    assert [f.kind for f in facts("yellow wall to my left and white dead end in front of me")].count(
        ViewKind.DEAD_END
    ) == 1


def test_yes_and_no_answers_to_the_commanders_questions():
    yes = answer(question("is the edge on your right?"), "yes")
    assert seen(yes) == {((R,), Label.WHITE, False)} and all(f.source == Source.ANSWER for f in yes)
    assert seen(answer(question("are you facing a red wall"), "yes")) == {((F,), Label.RED, False)}
    no = answer(question("Do you have red walls near you?"), "no")
    assert seen(no) == {((ANY,), Label.RED, True)} and no[0].distance.value == "near"
    # a choice: the side answered, for the question's first label
    assert seen(answer(question("is the red wall to the left or right of the yellow wall?"), "left")) == {
        ((L,), Label.RED, False)
    }
    # a label answered to "what is on your left": the question's side
    assert seen(answer(question("What is on your left"), "the edge of the maze")) == {((L,), Label.WHITE, False)}
    # "yes" to a choice says nothing
    assert answer(question("is the red wall to the left or right of the yellow wall?"), "yes") == []


def test_reported_turns():
    assert turn_steps("I rotated 180 degrees, and now I see a yellow wall close to me") == 4
    assert turn_steps("I turned left") == 2 and turn_steps("ok I turned to the right") == -2
    assert turn_steps("I am facing a single yellow wall") == 0
    assert question("can you turn around and tell me what you see?").turn == 4


@pytest.fixture(scope="module")
def bundled():
    maze = MazeLibrary().load("gen-000")
    graph = NavGraph.build(maze, "benchmark")
    rays = RayTable.build(maze, graph)
    return MazeContext("gen-000", graph), Scene.from_rays(rays.labels, rays.depth, graph.nodes)


SIDES = ("in front of me", "to my left", "behind me", "to my right")


def description(scene: Scene, node: int, heading: int) -> list[str]:
    """What a Driver at the pose would say: each label a third of a sector's rays hit, with the
    side, and "close" where most of its hits are near."""
    out = []
    for s, side in enumerate(SIDES):
        near, far = scene.near[node, heading, s], scene.far[node, heading, s]
        for label in np.flatnonzero(near + far >= 0.3):
            if label != Label.FLOOR:
                close = "close " if near[label] >= far[label] else ""
                out.append(f"a {Label(label).word} wall {close}{side}")
    return out


# The calibration is fitted on human Drivers, who name a part of the view ahead as often as all of
# it: a rule that names whatever fills a third of each view leans on what is ahead more than they do.
@pytest.mark.parametrize("weights, within", [(TUNED, 0.8), (HUMAN, 0.7)], ids=["tuned", "calibrated"])
def test_the_belief_settles_on_the_pose_a_description_was_written_from(bundled, weights: Weights, within: float):
    ctx, scene = bundled
    g = ctx.graph
    errors, gains = [], []
    for node in np.flatnonzero(ctx.main)[::37]:
        for heading in (0, 3):
            belief = Belief(scene, ctx.main, weights)
            for message in description(scene, node, heading):
                belief.message("navigator", message)
            logits = belief.node_logits()
            p = np.exp(logits - logits.max())
            p /= p.sum()
            around = g.dist[:, node] <= 0.25
            gains.append(p[around].sum() / around[ctx.main].mean())
            errors.append(g.dist[ctx.decide(logits), node])
    assert len(errors) >= 20
    assert np.mean(np.asarray(errors) <= 0.5) >= within  # the estimate within 0.5 m of the pose
    assert np.mean(gains) >= 10  # ten times the mass a uniform belief puts near it


def test_a_reported_turn_moves_the_belief_to_the_new_heading(bundled):
    ctx, scene = bundled
    node = int(np.flatnonzero(ctx.main)[37 * 3])
    belief = Belief(scene, ctx.main)
    for message in description(scene, node, 0):
        belief.message("navigator", message)
    belief.message("navigator", "I turned around")
    for message in description(scene, node, 4):
        belief.message("navigator", message)
    assert int(belief.log[node].argmax()) == 4
    assert belief.turned == 4  # what the calibration reads the true heading by
    # without the turn the two descriptions contradict each other at this pose
    still = Belief(scene, ctx.main)
    for message in description(scene, node, 0) + description(scene, node, 4):
        still.message("navigator", message)
    assert still.log[node].max() < belief.log[node].max()


def test_the_calibration_favours_the_shares_true_poses_show():
    rng = np.random.default_rng(0)
    records = [Record(Evidence.LABEL, 0.9, rng.uniform(0, 0.5, 200)) for _ in range(40)]
    records.append(Record(Evidence.EDGE, 0.9, rng.uniform(0, 0.5, 200)))  # once: kept near even
    fitted = fit(records)
    high, low = fitted.loglik(Evidence.LABEL, np.array([0.9, 0.2]))
    assert high > 2 and low < -2
    assert abs(fitted.log_ratio[Evidence.EDGE][-1]) < abs(high)
    assert fitted.loglik(Evidence.CORNER, np.array([0.9])) is None  # not fitted: the hand weights score it


def test_the_calibration_never_scores_more_of_a_view_below_less_of_it():
    rng = np.random.default_rng(0)
    # true poses show a little of the label more often than most of it: a dip, pooled flat
    records = [Record(Evidence.LABEL, share, rng.uniform(0, 1, 200)) for share in [0.1] * 30 + [0.9] * 10]
    ratio = fit(records).log_ratio[Evidence.LABEL]
    assert all(a <= b for a, b in zip(ratio, ratio[1:], strict=False))


def test_the_fitted_calibration_scores_a_named_label_where_it_is_seen_above_where_it_is_not():
    assert evidence(facts("a red wall to my left")[0]) == Evidence.LABEL
    assert evidence(facts("no red wall")[0]) is None  # negation: the hand weights
    assert len(FITTED.log_ratio[Evidence.LABEL]) == len(SHARE_EDGES) - 1
    for kind in (Evidence.LABEL, Evidence.EDGE):
        none, most = FITTED.loglik(kind, np.array([0.0, 1.0]))
        assert none < 0 < most


def test_eval_ldh_dialog_writes_the_summary_and_the_per_turn_curve(tmp_path):
    labels = wall_at_x(open_table(), 0.6, Label.BLUE, y_range=(0.4, 1.66))  # a strip along the west border
    Maze.from_labels(labels, "m1").save(tmp_path / "mazedata" / "m1")
    (tmp_path / "NDH-data").mkdir()
    (tmp_path / "NDH-data" / "val_seen.json").write_text("[]")
    (tmp_path / "LDH-data").mkdir()
    item = {
        "inst_idx": 0,
        "scan": "mazedata/m1/maze/maze.labelled.npz-jar-[1.4 0.7]-[0.5 0.5]",
        "target": "jar",
        "agent_pose": [0.3, 1.0, 3.14],
        "dialog_history": [
            {"role": "oracle", "message": "what do you see?"},
            {"role": "navigator", "message": "a red wall close in front of me, blue close behind me"},
            {"role": "oracle", "message": "is there a red wall on your left?"},
            {"role": "navigator", "message": "no"},
        ],
    }
    (tmp_path / "LDH-data" / "val_seen.json").write_text(
        json.dumps([item, {**item, "inst_idx": 1, "agent_pose": [0.3, 0.6, 3.14]}])
    )
    curve, plot = tmp_path / "out" / "curve.json", tmp_path / "out" / "curve.png"
    args = ["eval", "ldh", "--benchmark", str(tmp_path), "--split", "val_seen", "--agent", "center,dialog"]
    more = ["--json", "--curve", str(curve), "--plot", str(plot), "--versus", "dialog"]
    result = CliRunner().invoke(root, [*args, *more])
    assert result.exit_code == 0, result.output
    out = json.loads(result.output)
    summary = out["agents"]
    (test,) = out["tests"]
    assert (test["a"], test["b"], test["n"]) == ("center", "dialog", 2)
    assert test["mean_b"] == pytest.approx(summary["dialog"]["td_mean"])
    assert list(summary) == ["center", "dialog"]
    assert {"td_mean", "td_median", "acc_0.25", "acc_0.5"} <= set(summary["dialog"])
    # facing the border with the blue wall behind: in the strip
    assert summary["dialog"]["td_mean"] < summary["center"]["td_mean"]
    turns = json.loads(curve.read_text())
    assert turns["turns"] == [0, 1, 2] and turns["n"] == [2, 2, 2]
    dialog_td = turns["agents"]["dialog"]["td_mean"]
    assert dialog_td[0] == pytest.approx(turns["agents"]["center"]["td_mean"][0])  # nothing said yet: the centre
    assert dialog_td[-1] == pytest.approx(summary["dialog"]["td_mean"])
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

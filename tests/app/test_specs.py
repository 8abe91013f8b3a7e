"""Seat and backend specs: what a trial's record stores reads back as the same typed value, and
a malformed one is refused with what it should have been."""

import pytest

from sim.trial.specs import HUMAN, SIM, BackendKind, BackendSpec, SeatKind, SeatSpec


@pytest.mark.parametrize("text", ["human", "agent:dialog", "agent:seq2seq", "oracle:shortest"])
def test_a_seat_spec_reads_back_as_written(text):
    assert str(SeatSpec.parse(text)) == text


def test_a_seat_spec_says_who_holds_the_seat():
    assert SeatSpec.parse("human") == HUMAN and HUMAN.human
    agent = SeatSpec.parse("agent:dialog")
    assert agent.kind == SeatKind.AGENT and agent.name == "dialog" and not agent.human
    assert SeatSpec.parse("oracle:shortest").kind == SeatKind.ORACLE


@pytest.mark.parametrize("text", ["", "Human", "agent:", "agent", "robot:1", "cheater:x", ":dialog"])
def test_a_malformed_seat_spec_is_refused_with_the_forms_it_may_take(text):
    with pytest.raises(ValueError, match="'human', 'agent:<name>' or 'oracle:<name>'"):
        SeatSpec.parse(text)


@pytest.mark.parametrize("text", ["sim", "robot:1", "robot:42"])
def test_a_backend_spec_reads_back_as_written(text):
    assert str(BackendSpec.parse(text)) == text


def test_a_backend_spec_names_the_rover():
    assert BackendSpec.parse("sim") == SIM and SIM.robot_id is None
    rover = BackendSpec.parse("robot:42")
    assert rover.kind == BackendKind.ROBOT and rover.robot_id == 42
    assert rover == BackendSpec.robot(42) and str(BackendSpec.robot(7)) == "robot:7"


@pytest.mark.parametrize("text", ["robot:", "robot:x", "robot", "robot:-1"])
def test_a_rover_spec_without_an_id_is_refused(text):
    with pytest.raises(ValueError, match="expected 'robot:<id>'"):
        BackendSpec.parse(text)

"""The stepwise Driver's loop around refused turns: a claim refused while the trial is paused is
made again once it runs; any other refusal it asks about and does not repeat on its own."""

from sim.agents.stepwise import StepwiseDriver
from sim.agents.turns import (
    DoClaim,
    DoSay,
    Heard,
    Paused,
    Phase,
    PhaseChanged,
    Refused,
    Saw,
    SeatInfo,
    Speaker,
    TurnKind,
)


class AlwaysClaims(StepwiseDriver):
    def decide(self):
        return None


def _navigating() -> AlwaysClaims:
    driver = AlwaysClaims()
    driver.reset(SeatInfo(Speaker.DRIVER, 3))
    assert driver.perceive(PhaseChanged(Phase.NAVIGATING, 0, 3)) == []
    return driver


def test_a_claim_refused_while_paused_is_made_again_once_the_trial_runs():
    driver = _navigating()
    assert driver.perceive(Paused(True)) == []
    assert driver.perceive(Saw(0, None))[-1] == DoClaim()  # it does not know yet why it would fail
    assert driver.perceive(Refused(TurnKind.CLAIM, "the trial is paused")) == []
    assert driver.perceive(Heard(Speaker.COMMANDER, "hello?")) == []  # still paused: it waits
    assert driver.perceive(Paused(False))[-1] == DoClaim()


def test_another_refusal_it_asks_about_and_waits_to_be_told():
    driver = _navigating()
    assert driver.perceive(Saw(0, None))[-1] == DoClaim()
    (ask,) = driver.perceive(Refused(TurnKind.CLAIM, "there is no camera frame to send yet"))
    assert isinstance(ask, DoSay) and "no camera frame" in ask.text
    assert driver.perceive(Saw(1, None)) == []  # no loop of refused claims
    assert driver.perceive(Heard(Speaker.COMMANDER, "try again"))[-1] == DoClaim()

"""The stepwise Driver's loop around refused turns: a claim refused while the trial is paused is
made again once it runs; any other refusal it asks about and does not repeat on its own."""

from sim.agents.stepwise import StepwiseDriver
from sim.trial.agent import SeatInfo
from sim.trial.commands import Claim, Say
from sim.trial.percepts import Declined, Heard, PauseSet, PhaseBegan, Saw
from sim.trial.vocabulary import Phase, Role


class AlwaysClaims(StepwiseDriver):
    def decide(self):
        return None


def _navigating() -> AlwaysClaims:
    driver = AlwaysClaims()
    driver.reset(SeatInfo(Role.DRIVER, 3))
    assert driver.perceive(PhaseBegan(Phase.NAVIGATING, 0, 3)) == []
    return driver


def test_a_claim_refused_while_paused_is_made_again_once_the_trial_runs():
    driver = _navigating()
    assert driver.perceive(PauseSet(True)) == []
    assert driver.perceive(Saw(0, None))[-1] == Claim()  # it does not know yet why it would fail
    assert driver.perceive(Declined(Claim(), "the trial is paused")) == []
    assert driver.perceive(Heard(Role.COMMANDER, "hello?")) == []  # still paused: it waits
    assert driver.perceive(PauseSet(False))[-1] == Claim()


def test_another_refusal_it_asks_about_and_waits_to_be_told():
    driver = _navigating()
    assert driver.perceive(Saw(0, None))[-1] == Claim()
    (ask,) = driver.perceive(Declined(Claim(), "there is no camera frame to send yet"))
    assert isinstance(ask, Say) and "no camera frame" in ask.text
    assert driver.perceive(Saw(1, None)) == []  # no loop of refused claims
    assert driver.perceive(Heard(Role.COMMANDER, "try again"))[-1] == Claim()

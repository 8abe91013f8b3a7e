"""The team plan: whom the lobby pairs, and in which seats. Pure, so the rule is read and tested in
one place: prefer a partner the participant has not been teamed with (the paper: 16 people in 41
teams, each in about five), never a layout either has seen, roles balanced (whoever has commanded
more drives), and no new team for a participant who has their number of teams."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from app.trial.vocabulary import Role


@dataclass(frozen=True)
class History:
    """A waiting participant's study trials so far (the practice not counted)."""

    participant_id: int
    partners: frozenset[int]  # participant ids they have been teamed with
    commanded: int
    driven: int
    seen: frozenset[str]  # layouts they have played


@dataclass(frozen=True)
class Pairing:
    commander_id: int
    driver_id: int

    def role_of(self, participant_id: int) -> Role:
        return Role.COMMANDER if participant_id == self.commander_id else Role.DRIVER


def choose_pair(
    me: History, waiting: Sequence[History], layouts: frozenset[str], teams_per_participant: int
) -> Pairing | None:
    """`me` (the poller) with one of `waiting` (longest first): a new partner before a known one,
    then whoever waited longest; None where no one fits the plan."""

    def fits(other: History) -> bool:
        new = other.participant_id not in me.partners
        full = len(me.partners) >= teams_per_participant or len(other.partners) >= teams_per_participant
        return not (new and full) and bool(layouts - me.seen - other.seen)

    order = sorted(range(len(waiting)), key=lambda i: (waiting[i].participant_id in me.partners, i))
    for i in order:
        other = waiting[i]
        if other.participant_id != me.participant_id and fits(other):
            return roles(other, me)
    return None


def roles(first: History, second: History) -> Pairing:
    """Whoever has commanded more (net of driving) drives; on a tie `first` (who waited longer) commands."""
    if first.commanded - first.driven <= second.commanded - second.driven:
        return Pairing(first.participant_id, second.participant_id)
    return Pairing(second.participant_id, first.participant_id)

"""The team plan's pairing rule, pure: from who waits in the lobby and what each has played, the
next pair and their seats (or none). The lobby (`app.study.lobby`) gathers the histories from the
database and creates the trial; this module decides, so the rule is tested without a server."""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import dataclass


@dataclass(frozen=True)
class History:
    """A participant's study so far (the practice not counted)."""

    participant_id: int
    partners: frozenset[int] = frozenset()  # everyone they have been in a team with
    commanded: int = 0
    drove: int = 0
    layouts: frozenset[str] = frozenset()  # every layout they have seen, the practice's included

    @property
    def teams(self) -> int:
        return len(self.partners)

    @property
    def lean(self) -> int:
        """How far their roles lean to the Commander's seat."""
        return self.commanded - self.drove


@dataclass(frozen=True)
class Pair:
    commander: int
    driver: int


def plan_done(history: History, teams_per_participant: int) -> bool:
    """Reached the plan's teams: no more pairing, the completion code instead."""
    return history.teams >= teams_per_participant


def next_pair(
    asker: History, waiting: Sequence[History], layouts: Collection[str], teams_per_participant: int
) -> Pair | None:
    """The asker's partner among `waiting` (longest waiting first) and the seats, or None.

    A partner not yet teamed with the asker comes before one who was (then by waiting time); never
    one with whom no layout of `layouts` is left unseen by both; nobody who reached the plan's
    teams. The one whose roles lean more to commanding drives; on a tie the one who waited longer
    (the partner) commands."""
    if plan_done(asker, teams_per_participant):
        return None
    candidates = [
        (other.participant_id in asker.partners, order, other)
        for order, other in enumerate(waiting)
        if other.participant_id != asker.participant_id
        and not plan_done(other, teams_per_participant)
        and any(layout not in asker.layouts and layout not in other.layouts for layout in layouts)
    ]
    if not candidates:
        return None
    _, _, partner = min(candidates, key=lambda c: (c[0], c[1]))
    if asker.lean < partner.lean:
        return Pair(commander=asker.participant_id, driver=partner.participant_id)
    return Pair(commander=partner.participant_id, driver=asker.participant_id)

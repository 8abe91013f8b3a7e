"""The lobby: participants who arrive at different times wait; each lobby page's poll pairs the
poller with whoever waited longest and is still there (newcomers with newcomers, for a practice
trial on the study's bundled practice maze, set aside from scores), by the study's team plan (`app.study.plan`: a new
partner first, roles balanced, a layout neither has seen: the trial form's `suggest_maze`, on the
study's pool). A page that stops asking (a closed tab) is not paired; a waiter past the study's time-out is
told so. One participant is in one live trial at a time, so two browsers of one participant are
sent to the same seat, never two."""

from __future__ import annotations

import random
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

from sqlalchemy import or_, select
from sqlalchemy.orm import Session

from app.db.models import Participant, StudyParticipant, Team, Trial
from app.study.config import StudyConfig
from app.study.plan import History, Pairing, choose_pair, roles
from app.trial.lifecycle import live_trial_of
from app.trial.setup import TrialSetupError, create_team, create_trial, mazes_played, parse_targets, suggest_maze
from app.trial.vocabulary import Role


class LobbyError(ValueError):
    """A pairing that cannot be made; nothing was created."""


@dataclass(frozen=True)
class Seated:
    trial_id: int
    role: Role


@dataclass(frozen=True)
class Waiting:
    waiting: int  # participants in the lobby now, this one included


@dataclass(frozen=True)
class TimedOut:
    waited_s: float


@dataclass(frozen=True)
class AllPlayed:
    trials: int  # the study's trials_per_participant, all played


LobbyState = Seated | Waiting | TimedOut | AllPlayed
PRACTICE_REASON = "study practice: not scored"


def _aware(t: datetime) -> datetime:
    return t if t.tzinfo else t.replace(tzinfo=UTC)  # SQLite gives stamps back without their zone


def seat_of(trial: Trial, participant_id: int) -> Seated:
    return Seated(trial.id, Role.COMMANDER if trial.commander_id == participant_id else Role.DRIVER)


class Lobby:
    def __init__(self, db: Session, config: StudyConfig, layouts: Mapping[str, str], now_ns: int) -> None:
        self.db = db
        self.config = config
        # The pool's mazes (all but the practice maze when the pool is empty) -> their layouts.
        pool = set(config.maze_pool) or set(layouts) - {config.practice_maze}
        self.layouts = {m: layout for m, layout in layouts.items() if m in pool}
        practice = config.practice_maze
        self.practice_layouts: dict[str, str] = (
            {practice: layouts[practice]} if practice is not None and practice in layouts else {}
        )
        self.now_ns = now_ns

    def poll(self, enrolled: StudyParticipant, now: datetime) -> LobbyState:
        """This participant's lobby page asks: their seat, or how many wait (after pairing them if it can)."""
        live = live_trial_of(self.db, (enrolled.participant_id,))
        if live is not None:
            enrolled.lobby_since = None
            return seat_of(live, enrolled.participant_id)
        if self.played(enrolled) >= self.config.trials_per_participant:
            enrolled.lobby_since = None
            return AllPlayed(self.config.trials_per_participant)
        left = enrolled.lobby_seen is not None and (now - _aware(enrolled.lobby_seen)).total_seconds() > (
            self.config.lobby_presence_s
        )
        if enrolled.lobby_since is None or left:  # one whose page stopped asking waits anew on coming back
            enrolled.lobby_since = now
        enrolled.lobby_seen = now
        waited = (now - _aware(enrolled.lobby_since)).total_seconds()
        if waited > self.config.lobby_timeout_s:
            enrolled.lobby_since = None
            return TimedOut(waited)
        others = self.waiting(now, but=enrolled.id)
        practice = self.needs_practice(enrolled)
        if practice:  # newcomers practise together, whoever waited longest first
            partners = [o for o in others if self.needs_practice(o)]
            plan = roles(self.history(partners[0]), self.history(enrolled)) if partners else None
        else:
            players = [o for o in others if not self.needs_practice(o)]
            plan = choose_pair(
                self.history(enrolled),
                [self.history(o) for o in players],
                frozenset(self.layouts.values()),
                self.config.teams_per_participant,
            )
        if plan is not None:
            other = next(o for o in others if o.participant_id in (plan.commander_id, plan.driver_id))
            trial = self._pair(enrolled, other, practice, plan)
            if trial is not None:
                enrolled.lobby_since = other.lobby_since = None
                return seat_of(trial, enrolled.participant_id)
        return Waiting(len(others) + 1)

    def waiting(self, now: datetime, but: int | None = None) -> list[StudyParticipant]:
        """Who waits and is still there, longest first."""
        present = now - timedelta(seconds=self.config.lobby_presence_s)
        rows = self.db.scalars(
            select(StudyParticipant)
            .where(
                StudyParticipant.study == self.config.name,
                StudyParticipant.lobby_since.is_not(None),
                StudyParticipant.withdrawn_at.is_(None),
                StudyParticipant.id != (but or -1),
            )
            .order_by(StudyParticipant.lobby_since, StudyParticipant.id)
        )
        return [e for e in rows if e.lobby_seen is not None and _aware(e.lobby_seen) >= present]

    def _study_trials(self, participant_id: int) -> list[Trial]:
        """The participant's study trials, the practice not counted."""
        return list(
            self.db.scalars(
                select(Trial).where(
                    Trial.study == self.config.name,
                    or_(Trial.commander_id == participant_id, Trial.driver_id == participant_id),
                    or_(Trial.excluded_reason.is_(None), Trial.excluded_reason != PRACTICE_REASON),
                )
            )
        )

    def history(self, enrolled: StudyParticipant) -> History:
        pid = enrolled.participant_id
        trials = self._study_trials(pid)
        return History(
            participant_id=pid,
            partners=frozenset(
                seat for t in trials for seat in (t.commander_id, t.driver_id) if seat is not None and seat != pid
            ),
            commanded=sum(t.commander_id == pid for t in trials),
            driven=sum(t.driver_id == pid for t in trials),
            seen=frozenset(self.layouts.get(maze, maze) for maze in mazes_played(self.db, (pid,))),
        )

    def pair(self, a: StudyParticipant, b: StudyParticipant) -> Trial:
        """The experimenter pairs two participants by hand (waiting or not): a practice trial when
        both still need one, else a study trial; `LobbyError` says why not."""
        if a.id == b.id:
            raise LobbyError("choose two different participants")
        if a.withdrawn_at is not None or b.withdrawn_at is not None:
            raise LobbyError("a withdrawn participant cannot be paired")
        trial = self._pair(
            a, b, self.needs_practice(a) and self.needs_practice(b), roles(self.history(a), self.history(b))
        )
        if trial is None:
            raise LobbyError("one of them is in a live trial, or the pool has no layout both have not seen")
        a.lobby_since = b.lobby_since = None
        return trial

    def played(self, enrolled: StudyParticipant) -> int:
        """The participant's study trials so far, the practice not counted."""
        return len(self._study_trials(enrolled.participant_id))

    def needs_practice(self, enrolled: StudyParticipant) -> bool:
        if not self.practice_layouts:
            return False
        practised = select(Trial.id).where(
            Trial.study == self.config.name,
            Trial.excluded_reason == PRACTICE_REASON,
            or_(Trial.commander_id == enrolled.participant_id, Trial.driver_id == enrolled.participant_id),
        )
        return self.db.scalar(practised.limit(1)) is None

    def _pair(self, me: StudyParticipant, other: StudyParticipant, practice: bool, plan: Pairing) -> Trial | None:
        """A trial of the two on a layout neither has seen (the practice maze when they need
        practice), or None where there is none."""
        a, b = sorted((me.participant_id, other.participant_id))
        team = self.db.scalar(select(Team).where(Team.member_a_id == a, Team.member_b_id == b))
        if team is None:
            codes = self.db.scalars(select(Participant.name).where(Participant.id.in_((a, b))).order_by(Participant.id))
            team = create_team(self.db, " & ".join(codes), a, b)
        layouts = self.practice_layouts if practice else self.layouts
        maze = suggest_maze(self.db, team, layouts)
        if maze is None:
            return None
        try:
            trial = create_trial(
                self.db,
                team_id=team.id,
                maze=maze,
                targets=parse_targets("random", random.Random()),
                backend="sim",
                driver="human",
                commander_id=plan.commander_id,
                layouts=layouts,
                now_ns=self.now_ns,
            )
        except TrialSetupError:
            return None  # the other was seated by a poll of their own meanwhile
        trial.study = self.config.name
        if practice:  # set aside like an excluded trial: off the leaderboard and the exports, log kept
            trial.excluded_reason = PRACTICE_REASON
        return trial

"""The lobby: participants who arrive at different times wait; each lobby page's poll pairs the
poller by the team plan (`app.study.pairing`: a new partner before an old one, then whoever waited
longest and is still there; roles balanced; newcomers with newcomers, for a practice trial on the
study's bundled practice maze, set aside from scores), on a maze of a layout neither has seen (the
trial form's `suggest_maze`, on the study's pool). A page that stops asking (a closed tab) is not paired; a waiter past the study's time-out is
told so; one who leaves (the button, or the page closing: it says so at once) is not paired from
then on. One participant is in one live trial at a time, so two browsers of one participant are
sent to the same seat, never two."""

from __future__ import annotations

import random
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

from sqlalchemy import or_, select
from sqlalchemy.orm import Session

from app.db.models import Participant, StudyParticipant, Team, Trial
from app.study.config import StudyConfig, StudyOutcome
from app.study.pairing import History, Pair, next_pair, plan_done
from app.trial.lifecycle import live_trial_of
from app.trial.setup import (
    TrialSetupError,
    create_team,
    create_trial,
    layouts_seen_by,
    never_joined,
    parse_targets,
    restart_trial,
    suggest_maze,
)
from sim.trial.vocabulary import Phase, Role


class LobbyError(ValueError):
    """A pairing that cannot be made; nothing was created."""


@dataclass(frozen=True)
class Seated:
    trial_id: int
    role: Role
    paired_now: bool = False  # this ask made the pair: the seats' join time-out starts


@dataclass(frozen=True)
class Waiting:
    waiting: int  # participants in the lobby now, this one included


@dataclass(frozen=True)
class TimedOut:
    waited_s: float


@dataclass(frozen=True)
class AllPlayed:
    trials: int  # study trials played (the practice not counted)
    teams: int  # teams they were in


@dataclass(frozen=True)
class Ended:
    """Their way through the study has ended (`Enrolment.outcome` says how): never paired again."""


@dataclass(frozen=True)
class TimeUp:
    """The study's `time_limit_s` since they consented has passed: their way ends here."""


LobbyState = Seated | Waiting | TimedOut | AllPlayed | Ended | TimeUp
PRACTICE_REASON = "study practice: not scored"


def aware(t: datetime) -> datetime:
    return t if t.tzinfo else t.replace(tzinfo=UTC)  # SQLite gives stamps back without their zone


def end_wait(enrolled: StudyParticipant, until: datetime) -> None:
    """Their wait in the lobby ends at `until`: its time is added to what they have waited, each
    moment once (a wait that restarts from an earlier pairing is not counted twice)."""
    if enrolled.lobby_since is not None:
        start = aware(enrolled.lobby_since)
        if enrolled.lobby_waited_to is not None:
            start = max(start, aware(enrolled.lobby_waited_to))
        if until > start:
            enrolled.lobby_waited_s = (enrolled.lobby_waited_s or 0.0) + (until - start).total_seconds()
            enrolled.lobby_waited_to = until
    enrolled.lobby_since = None


def waited_s(enrolled: StudyParticipant) -> float:
    """Seconds they have waited in the lobby, a wait still going counted to their page's last ask."""
    waited = enrolled.lobby_waited_s or 0.0
    if enrolled.lobby_since is not None and enrolled.lobby_seen is not None:
        start = aware(enrolled.lobby_since)
        if enrolled.lobby_waited_to is not None:
            start = max(start, aware(enrolled.lobby_waited_to))
        waited += max(0.0, (aware(enrolled.lobby_seen) - start).total_seconds())
    return waited


def seat_of(trial: Trial, participant_id: int) -> Seated:
    return Seated(trial.id, Role.COMMANDER if trial.commander_id == participant_id else Role.DRIVER)


class Lobby:
    def __init__(self, db: Session, config: StudyConfig, layouts: Mapping[str, str], now_ns: int) -> None:
        self.db = db
        self.config = config
        self.all_layouts = layouts
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
            end_wait(enrolled, now)
            return seat_of(live, enrolled.participant_id)
        if enrolled.completed_at is not None:
            return Ended()
        done = self.done(enrolled)
        if done is not None:
            end_wait(enrolled, now)
            return done
        if self.time_up(enrolled, now):
            return TimeUp()
        left = enrolled.lobby_seen is not None and (now - aware(enrolled.lobby_seen)).total_seconds() > (
            self.config.lobby_presence_s
        )
        if enrolled.lobby_since is None or left:  # one whose page stopped asking waits anew on coming back
            if left and enrolled.lobby_seen is not None:
                end_wait(enrolled, aware(enrolled.lobby_seen))  # the wait they left: counted to their last ask
            enrolled.lobby_since = self._stood_up(enrolled) or now
        enrolled.lobby_seen = now
        waited = (now - aware(enrolled.lobby_since)).total_seconds()
        if waited > self.config.lobby_timeout_s:
            end_wait(enrolled, now)
            return TimedOut(waited)
        others = self.waiting(now, but=enrolled.id)
        practice = self.needs_practice(enrolled)
        alike = [other for other in others if self.needs_practice(other) == practice]  # newcomers practise together
        trial = self._pair(enrolled, alike, practice)
        if trial is not None:
            for seated in (enrolled, *alike):
                if trial.commander_id == seated.participant_id or trial.driver_id == seated.participant_id:
                    end_wait(seated, now)
            return Seated(trial.id, seat_of(trial, enrolled.participant_id).role, paired_now=True)
        return Waiting(len(others) + 1)

    def time_up(self, enrolled: StudyParticipant, now: datetime) -> bool:
        limit = self.config.time_limit_s
        return limit is not None and (now - aware(enrolled.created_at)).total_seconds() > limit

    def finishing(self, enrolled: StudyParticipant, now: datetime) -> StudyOutcome | None:
        """What "I have finished" ends with now: the plan played (not mid-trial), the study's time
        up, a partner who never came (nothing else played), a partial completion after at least one
        trial; None: nothing played yet, so nothing to finish."""
        live = live_trial_of(self.db, (enrolled.participant_id,))
        if live is None and self.done(enrolled) is not None:
            return StudyOutcome.completed
        if self.time_up(enrolled, now):
            return StudyOutcome.timed_out
        if self.finished(enrolled):
            return StudyOutcome.partial
        return StudyOutcome.no_partner if self._stood_up(enrolled) is not None else None

    def finished(self, enrolled: StudyParticipant) -> int:
        """Study trials played to their end (the practice, trials never joined and a live one not counted)."""
        return sum(1 for t in self._trials(enrolled) if Phase(t.phase).over)

    def leave(self, enrolled: StudyParticipant) -> None:
        """They left the lobby (its button, or their page closing): nobody is paired with them from
        now on, and coming back is a new wait."""
        end_wait(enrolled, datetime.now(UTC))
        enrolled.lobby_seen = None

    def _stood_up(self, enrolled: StudyParticipant) -> datetime | None:
        """When their last trial was paired, if it was aborted because the partner never opened
        their seat while they had opened theirs: they go back to the head of the lobby."""
        pid = enrolled.participant_id
        last = self.db.scalars(
            select(Trial)
            .where(Trial.study == self.config.name, or_(Trial.commander_id == pid, Trial.driver_id == pid))
            .order_by(Trial.id.desc())
        ).first()
        if last is None:
            return None
        absent = never_joined(self.db, (last.id,)).get(last.id, [])
        mine = Role.COMMANDER if last.commander_id == pid else Role.DRIVER
        return aware(last.created_at) if absent and mine not in absent else None

    def done(self, enrolled: StudyParticipant) -> AllPlayed | None:
        """The plan is played out for this participant: its trials, or its teams."""
        played = self.played(enrolled)
        history = self.history(enrolled)
        if played >= self.config.trials_per_participant or plan_done(history, self.config.teams_per_participant):
            return AllPlayed(played, history.teams)
        return None

    def view(self, now: datetime) -> list[dict[str, object]]:
        """The experimenter's live lobby: who waits (longest first), how long, and their plan so far."""
        rows: list[dict[str, object]] = []
        for enrolled in self.waiting(now):
            history = self.history(enrolled)
            code = self.db.scalar(select(Participant.name).where(Participant.id == enrolled.participant_id))
            since = enrolled.lobby_since
            rows.append(
                {
                    "code": code,
                    "waited_s": round((now - aware(since)).total_seconds()) if since is not None else 0,
                    "teams": history.teams,
                    "commanded": history.commanded,
                    "drove": history.drove,
                    "practice": self.needs_practice(enrolled),
                }
            )
        return rows

    def waiting(self, now: datetime, but: int | None = None) -> list[StudyParticipant]:
        """Who waits and is still there, longest first."""
        present = now - timedelta(seconds=self.config.lobby_presence_s)
        rows = self.db.scalars(
            select(StudyParticipant)
            .where(
                StudyParticipant.study == self.config.name,
                StudyParticipant.lobby_since.is_not(None),
                StudyParticipant.withdrawn_at.is_(None),
                StudyParticipant.completed_at.is_(None),
                StudyParticipant.id != (but or -1),
            )
            .order_by(StudyParticipant.lobby_since, StudyParticipant.id)
        )
        return [e for e in rows if e.lobby_seen is not None and aware(e.lobby_seen) >= present]

    def history(self, enrolled: StudyParticipant) -> History:
        """What the pairing rule knows of a participant: partners and seats in the study's trials
        (the practice not counted) and every layout they have seen."""
        pid = enrolled.participant_id
        partners: set[int] = set()
        commanded = drove = 0
        for trial in self._trials(enrolled):
            if trial.commander_id == pid:
                commanded += 1
                partner = trial.driver_id
            else:
                drove += 1
                partner = trial.commander_id
            if partner is not None:
                partners.add(partner)
        seen = frozenset(layouts_seen_by(self.db, (pid,), self.all_layouts))
        return History(pid, frozenset(partners), commanded, drove, seen)

    def pair(self, a: StudyParticipant, b: StudyParticipant) -> Trial:
        """The experimenter pairs two participants by hand (waiting or not): a practice trial when
        both still need one, else a study trial; `LobbyError` says why not."""
        if a.id == b.id:
            raise LobbyError("choose two different participants")
        if a.withdrawn_at is not None or b.withdrawn_at is not None:
            raise LobbyError("a withdrawn participant cannot be paired")
        if a.completed_at is not None or b.completed_at is not None:
            raise LobbyError("one of them has ended their way through the study")
        for enrolled in (a, b):
            if live_trial_of(self.db, (enrolled.participant_id,)) is not None:
                raise LobbyError("one of them is in a live trial")
            if self.done(enrolled) is not None:
                raise LobbyError("one of them has played the plan's trials or teams")
        trial = self._pair(a, [b], self.needs_practice(a) and self.needs_practice(b))
        if trial is None:
            raise LobbyError("the pool has no layout both have not seen")
        for enrolled in (a, b):
            end_wait(enrolled, datetime.now(UTC))
        return trial

    def restart(self, trial_id: int) -> Trial:
        """The experimenter restarts an aborted trial of the study: it stays in the study, on a
        maze of its pool (a practice whose map nobody saw on the practice maze again, still set
        aside from scores), its seats given the study's join deadline from now."""
        old = self.db.get(Trial, trial_id)
        if old is None or old.study != self.config.name:
            raise TrialSetupError(f"trial {trial_id} is not a trial of study {self.config.name!r}")
        practice = old.excluded_reason == PRACTICE_REASON
        if practice and Role.COMMANDER not in never_joined(self.db, (old.id,)).get(old.id, []):
            raise TrialSetupError(
                f"trial {trial_id} was a practice whose map was seen: a practice is played once, and the "
                "lobby pairs these participants for the study's trials next"
            )
        trial = restart_trial(
            self.db,
            trial_id,
            self.practice_layouts if practice else self.layouts,
            self.now_ns,
            join_timeout_s=self.config.join_timeout_s,
            time_cap_s=self.config.practice_time_cap_s if practice else None,
        )
        if practice:
            trial.excluded_reason = PRACTICE_REASON
        return trial

    def _trials(self, enrolled: StudyParticipant) -> list[Trial]:
        """The participant's study trials: not the practice, nor one aborted with a seat never opened."""
        pid = enrolled.participant_id
        trials = list(
            self.db.scalars(
                select(Trial).where(
                    Trial.study == self.config.name,
                    or_(Trial.commander_id == pid, Trial.driver_id == pid),
                    or_(Trial.excluded_reason.is_(None), Trial.excluded_reason != PRACTICE_REASON),
                )
            )
        )
        unopened = never_joined(self.db, [t.id for t in trials])
        return [t for t in trials if t.id not in unopened]

    def played(self, enrolled: StudyParticipant) -> int:
        """The participant's study trials so far (the practice, and trials never joined, not counted)."""
        return len(self._trials(enrolled))

    def needs_practice(self, enrolled: StudyParticipant) -> bool:
        if not self.practice_layouts:
            return False
        practised = select(Trial.id).where(
            Trial.study == self.config.name,
            Trial.excluded_reason == PRACTICE_REASON,
            or_(Trial.commander_id == enrolled.participant_id, Trial.driver_id == enrolled.participant_id),
        )
        return self.db.scalar(practised.limit(1)) is None

    def _pair(self, me: StudyParticipant, others: list[StudyParticipant], practice: bool) -> Trial | None:
        """A trial of `me` and the partner the plan gives among `others`, on a layout neither has
        seen (the practice maze when they need practice), or None where the plan gives none."""
        layouts = self.practice_layouts if practice else self.layouts
        candidates = [other for other in others if self.done(other) is None]
        pair = next_pair(
            self.history(me),
            [self.history(other) for other in candidates],
            set(layouts.values()),
            self.config.teams_per_participant,
        )
        if pair is None:
            return None
        return self._create(pair, layouts, practice)

    def _create(self, pair: Pair, layouts: Mapping[str, str], practice: bool) -> Trial | None:
        a, b = sorted((pair.commander, pair.driver))
        team = self.db.scalar(select(Team).where(Team.member_a_id == a, Team.member_b_id == b))
        if team is None:
            codes = self.db.scalars(select(Participant.name).where(Participant.id.in_((a, b))).order_by(Participant.id))
            team = create_team(self.db, " & ".join(codes), a, b)
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
                commander_id=pair.commander,
                layouts=layouts,
                now_ns=self.now_ns,
                join_timeout_s=self.config.join_timeout_s,
                time_cap_s=self.config.practice_time_cap_s if practice else None,
            )
        except TrialSetupError:
            return None  # the other was seated by a poll of their own meanwhile
        trial.study = self.config.name
        if practice:  # set aside like an excluded trial: off the leaderboard and the exports, log kept
            trial.excluded_reason = PRACTICE_REASON
        return trial

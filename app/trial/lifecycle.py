"""What the experimenter may undo or set aside: deleting participants, teams and robots nothing
uses, excluding a trial (with a reason) from the leaderboard and exports, and the rule that a
participant is seated in one live trial at a time. Each refusal names why."""

from __future__ import annotations

from typing import TypeVar

from sqlalchemy import or_, select
from sqlalchemy.orm import Session

from app.db.models import Participant, Robot, Team, Trial
from sim.trial.specs import BackendSpec
from sim.trial.vocabulary import Phase, Role

LIVE_PHASES = tuple(str(p) for p in Phase if not p.over)
MAX_REASON = 500


class Refused(ValueError):
    """A change that would lose or contradict what is recorded; the message says why."""


Row = TypeVar("Row", Participant, Team, Robot, Trial)


def _existing(db: Session, model: type[Row], row_id: int, what: str) -> Row:
    row = db.get(model, row_id)
    if row is None:
        raise Refused(f"{what} {row_id} does not exist")
    return row


def live_trial_of(db: Session, participant_ids: tuple[int, ...]) -> Trial | None:
    """A trial not yet over in which one of these participants holds a seat, or whose team they
    are in (a team has one live trial at a time)."""
    teams = select(Team.id).where(or_(Team.member_a_id.in_(participant_ids), Team.member_b_id.in_(participant_ids)))
    seated = or_(
        Trial.commander_id.in_(participant_ids), Trial.driver_id.in_(participant_ids), Trial.team_id.in_(teams)
    )
    return db.scalars(select(Trial).where(Trial.phase.in_(LIVE_PHASES), seated).order_by(Trial.id).limit(1)).first()


def delete_participant(db: Session, participant_id: int) -> None:
    participant = _existing(db, Participant, participant_id, "participant")
    team = db.scalars(
        select(Team.name).where(or_(Team.member_a_id == participant_id, Team.member_b_id == participant_id))
    ).first()
    if team is not None:
        raise Refused(f"participant {participant.name!r} is a member of team {team!r}: delete the team first")
    db.delete(participant)


def delete_team(db: Session, team_id: int) -> None:
    team = _existing(db, Team, team_id, "team")
    trials = db.scalars(select(Trial.id).where(Trial.team_id == team_id)).all()
    if trials:
        listed = ", ".join(str(t) for t in trials[:5]) + (", ..." if len(trials) > 5 else "")
        raise Refused(f"team {team.name!r} has played trials ({listed}): exclude them instead")
    db.delete(team)


def delete_robot(db: Session, robot_id: int, connected: bool) -> None:
    """`connected`: whether the robot is on its link now (a connected robot is kept)."""
    robot = _existing(db, Robot, robot_id, "robot")
    if connected:
        raise Refused(f"robot {robot.name!r} is connected: stop it first")
    if robot.role == Role.DRIVER:
        used = db.scalars(select(Trial.id).where(Trial.backend == str(BackendSpec.robot(robot_id))).limit(1)).first()
        if used is not None:
            raise Refused(f"robot {robot.name!r} is the robot of trial {used}: its recordings name it")
    db.delete(robot)


def exclude_trial(db: Session, trial_id: int, reason: str) -> None:
    """Set an ended trial aside from the leaderboard and exports; `reason` is kept and shown."""
    trial = _existing(db, Trial, trial_id, "trial")
    reason = " ".join(reason.split())
    if not reason:
        raise Refused("give a reason for excluding the trial")
    if len(reason) > MAX_REASON:
        raise Refused(f"the reason is {len(reason)} characters; at most {MAX_REASON}")
    if trial.phase in LIVE_PHASES:
        raise Refused(f"trial {trial_id} is {trial.phase}: abort it before excluding it")
    if trial.excluded_reason is not None:
        raise Refused(f"trial {trial_id} is already excluded: {trial.excluded_reason}")
    trial.excluded_reason = reason

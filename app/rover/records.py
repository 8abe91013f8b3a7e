"""A robot's record and its token: registering one (`create_robot`, the token shown once,
stored hashed) and finding the robot a token belongs to."""

from __future__ import annotations

import hashlib
import secrets

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.db.models import Robot
from sim.trial.vocabulary import ROBOT_ROLES


class RobotSetupError(ValueError):
    """A robot that cannot be registered as asked; the message names the field."""


def hash_token(token: str) -> str:
    # Tokens are 256 random bits, so one SHA-256 is as good as a slow hash and can be looked up.
    return "sha256$" + hashlib.sha256(token.encode()).hexdigest()


def create_robot(db: Session, name: str, role: str = "driver") -> tuple[Robot, str]:
    """Register a robot; returns it with its token, which is stored only hashed (show it once)."""
    name = name.strip()
    if not name:
        raise RobotSetupError("robot name is empty")
    if role not in ROBOT_ROLES:
        raise RobotSetupError(f"robot role {role!r}: expected one of {', '.join(ROBOT_ROLES)}")
    if db.scalar(select(Robot).where(Robot.name == name)) is not None:
        raise RobotSetupError(f"robot {name!r} already exists")
    # Hex, not base64: a token starting with '-' would read as an option on the rover's command line.
    token = secrets.token_hex(32)
    robot = Robot(name=name, role=role, token_hash=hash_token(token))
    db.add(robot)
    db.flush()
    return robot, token


def robot_for_token(db: Session, token: str) -> Robot | None:
    return db.scalar(select(Robot).where(Robot.token_hash == hash_token(token)))

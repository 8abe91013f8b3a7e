"""Accounts: experimenters and annotators, made by `robotslang admin create` or the experimenter's
annotation page (one rule for both)."""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from app.db.models import Experimenter
from app.security import AccountRole, set_password

MIN_PASSWORD = 8


class AccountError(ValueError):
    """What is wrong with a new account's name or password; the message says so."""


def check_password(password: str) -> None:
    if len(password) < MIN_PASSWORD:
        raise AccountError(f"the password must be at least {MIN_PASSWORD} characters")


def create_account(db: Session, name: str, password: str, role: AccountRole) -> Experimenter:
    name = name.strip()
    if not name or len(name) > 80:
        raise AccountError("the name must be 1 to 80 characters")
    check_password(password)
    if db.scalar(select(Experimenter.id).where(Experimenter.name == name)) is not None:
        raise AccountError(f"an account named {name!r} already exists")
    account = Experimenter(name=name, role=role)
    set_password(account, password)
    db.add(account)
    db.flush()
    return account

"""Who may do what: signed seat tokens, experimenter passwords and login sessions.

A seat token names one trial and one role; it is checked on every page and every socket
message, so a Commander's link can never move the robot or see a frame.
"""

from __future__ import annotations

import hashlib
import hmac
import secrets
from dataclasses import dataclass

from itsdangerous import BadSignature, SignatureExpired, URLSafeSerializer, URLSafeTimedSerializer

SEAT_ROLES = ("commander", "driver")
SESSION_COOKIE = "robotslang_session"
SESSION_MAX_AGE_S = 12 * 3600


class InvalidToken(ValueError):
    """A token that is forged, for another trial or role, or expired."""


@dataclass(frozen=True)
class Seat:
    trial_id: int
    role: str


class SeatTokens:
    def __init__(self, secret: str) -> None:
        self._serializer = URLSafeSerializer(secret, salt="seat")

    def issue(self, trial_id: int, role: str) -> str:
        if role not in SEAT_ROLES:
            raise ValueError(f"unknown seat role {role!r}; expected one of {', '.join(SEAT_ROLES)}")
        return self._serializer.dumps({"t": trial_id, "r": role})

    def verify(self, token: str) -> Seat:
        try:
            data = self._serializer.loads(token)
            seat = Seat(int(data["t"]), str(data["r"]))
        except (BadSignature, KeyError, TypeError, ValueError):
            raise InvalidToken("seat token is not valid (forged or damaged link)") from None
        if seat.role not in SEAT_ROLES:
            raise InvalidToken(f"seat token names an unknown role {seat.role!r}")
        return seat


class Sessions:
    """Experimenter login: a signed, timed cookie holding the experimenter's id."""

    def __init__(self, secret: str) -> None:
        self._serializer = URLSafeTimedSerializer(secret, salt="experimenter-session")

    def issue(self, experimenter_id: int) -> str:
        return self._serializer.dumps({"e": experimenter_id})

    def verify(self, cookie: str | None) -> int | None:
        if not cookie:
            return None
        try:
            return int(self._serializer.loads(cookie, max_age=SESSION_MAX_AGE_S)["e"])
        except (BadSignature, SignatureExpired, KeyError, TypeError, ValueError):
            return None


def hash_password(password: str) -> str:
    salt = secrets.token_bytes(16)
    digest = hashlib.scrypt(password.encode(), salt=salt, n=2**14, r=8, p=1)
    return f"scrypt${salt.hex()}${digest.hex()}"


def verify_password(password: str, stored: str) -> bool:
    try:
        scheme, salt_hex, digest_hex = stored.split("$")
    except ValueError:
        return False
    if scheme != "scrypt":
        return False
    digest = hashlib.scrypt(password.encode(), salt=bytes.fromhex(salt_hex), n=2**14, r=8, p=1)
    return hmac.compare_digest(digest.hex(), digest_hex)

"""Who may do what: signed seat tokens, experimenter passwords, login sessions and CSRF tokens.

A seat token names one trial and one role; it is checked on every page and every socket
message, so a Commander's link can never move the robot or see a frame.
"""

from __future__ import annotations

import hashlib
import hmac
from dataclasses import dataclass
from enum import StrEnum
from functools import lru_cache, partial

from argon2 import PasswordHasher
from argon2.exceptions import InvalidHashError, VerificationError
from itsdangerous import BadSignature, SignatureExpired, URLSafeTimedSerializer
from sqlalchemy.orm import Session, sessionmaker

from app.db.models import Experimenter
from app.i18n import Text

SEAT_ROLES = ("commander", "driver")
SESSION_COOKIE = "robotslang_session"
ANNOTATOR_COOKIE = "robotslang_annotator"
SESSION_MAX_AGE_S = 12 * 3600
TOKENS_VERIFIED_KEPT = 4096  # genuine seat tokens remembered (two seats per live trial)
# argon2id with the library's RFC 9106 low-memory profile; the parameters travel in each hash.
HASHER = PasswordHasher()


class InvalidToken(ValueError):
    """A token that is forged, for another trial or role, or expired."""


class ExpiredLink(InvalidToken):
    """A genuine join link shown longer ago than `join_link_ttl_s`."""


@dataclass(frozen=True)
class Seat:
    trial_id: int
    role: str


class SeatTokens:
    """Join links. Any genuine token keeps its open seat working; `admit` (pages and socket upgrades)
    also refuses links older than `ttl_s`, counted from when the experimenter's page showed them."""

    def __init__(self, secret: str, ttl_s: float | None = None) -> None:
        self._serializer = URLSafeTimedSerializer(secret, salt="seat")
        self.ttl_s = ttl_s
        # Every message of a seat carries its token: a genuine one is checked once (itsdangerous
        # derives its key and the HMAC anew on each check, about a third of a message's validation).
        # A refused token raises, and lru_cache keeps no exception: forgeries are checked every time.
        self._verified = lru_cache(maxsize=TOKENS_VERIFIED_KEPT)(partial(self._load, max_age=None))

    def issue(self, trial_id: int, role: str) -> str:
        if role not in SEAT_ROLES:
            raise ValueError(f"unknown seat role {role!r}; expected one of {', '.join(SEAT_ROLES)}")
        return self._serializer.dumps({"t": trial_id, "r": role})

    def verify(self, token: str) -> Seat:
        return self._verified(token)

    def admit(self, token: str) -> Seat:
        return self._load(token, max_age=self.ttl_s)

    def _load(self, token: str, max_age: float | None) -> Seat:
        try:
            # itsdangerous compares ages as numbers; its hint says int where a float works the same.
            data = self._serializer.loads(token, max_age=max_age)  # type: ignore[arg-type]
            seat = Seat(int(data["t"]), str(data["r"]))
        except SignatureExpired:
            raise ExpiredLink(Text("this join link has expired: ask the experimenter for a new one")) from None
        except (BadSignature, KeyError, TypeError, ValueError):
            raise InvalidToken("seat token is not valid (forged or damaged link)") from None
        if seat.role not in SEAT_ROLES:
            raise InvalidToken(f"seat token names an unknown role {seat.role!r}")
        return seat


@dataclass(frozen=True)
class StudyPass:
    study_id: int
    participant_id: int


class StudyTokens:
    """A participant's link to an LDH study: names the study and the participant (another salt
    than seat links, so neither opens the other). Valid as long as the study holds the participant."""

    def __init__(self, secret: str) -> None:
        self._serializer = URLSafeTimedSerializer(secret, salt="ldh-study")

    def issue(self, study_id: int, participant_id: int) -> str:
        return self._serializer.dumps({"s": study_id, "p": participant_id})

    def verify(self, token: str) -> StudyPass:
        try:
            data = self._serializer.loads(token)
            return StudyPass(int(data["s"]), int(data["p"]))
        except (BadSignature, KeyError, TypeError, ValueError):
            raise InvalidToken("study link is not valid (forged or damaged link)") from None


class AccountRole(StrEnum):
    """What an account's login opens: the experimenter's pages, or only the annotation pages."""

    EXPERIMENTER = "experimenter"
    ANNOTATOR = "annotator"


@dataclass(frozen=True)
class Login:
    """An experimenter's live login: valid while the account's session version is unchanged."""

    experimenter_id: int
    version: int


class Sessions:
    """Login: a signed, timed cookie naming the account and its session version. Logging out or
    changing the password bumps the version, which ends every cookie issued before. Each role has
    its own salt and accepts only its own accounts, so an annotator's cookie opens no
    experimenter page (and an experimenter's no annotator queue)."""

    def __init__(self, secret: str, db: sessionmaker[Session], role: AccountRole = AccountRole.EXPERIMENTER) -> None:
        salt = "experimenter-session" if role == AccountRole.EXPERIMENTER else f"{role}-session"
        self._serializer = URLSafeTimedSerializer(secret, salt=salt)
        self._db = db
        self.role = role

    def issue(self, experimenter_id: int) -> str:
        with self._db() as db:
            experimenter = db.get(Experimenter, experimenter_id)
        if experimenter is None:
            raise LookupError(f"experimenter {experimenter_id} does not exist")
        version = experimenter.session_version
        return self._serializer.dumps({"e": experimenter_id, "v": version})

    def verify(self, cookie: str | None) -> Login | None:
        if not cookie:
            return None
        try:
            data = self._serializer.loads(cookie, max_age=SESSION_MAX_AGE_S)
            login = Login(int(data["e"]), int(data["v"]))
        except (BadSignature, SignatureExpired, KeyError, TypeError, ValueError):
            return None
        with self._db() as db:
            user = db.get(Experimenter, login.experimenter_id)
        genuine = user is not None and user.session_version == login.version and user.role == self.role
        return login if genuine else None

    def end(self, login: Login) -> None:
        """Log out: every cookie of this account stops working."""
        with self._db.begin() as db:
            user = db.get(Experimenter, login.experimenter_id)
            if user is not None and user.session_version == login.version:
                user.session_version += 1


class CsrfTokens:
    """The token a page's forms and scripts send back: bound to the browser's cookie and, once
    logged in, to the login, so a token read anywhere else is worth nothing."""

    def __init__(self, secret: str) -> None:
        self._key = hashlib.sha256(b"csrf\0" + secret.encode()).digest()

    def issue(self, browser_id: str, login: Login | None) -> str:
        bound = f"{browser_id}|{login.experimenter_id}.{login.version}" if login else f"{browser_id}|"
        return hmac.new(self._key, bound.encode(), hashlib.sha256).hexdigest()

    def verify(self, token: str, browser_id: str, login: Login | None) -> bool:
        return hmac.compare_digest(token.encode(), self.issue(browser_id, login).encode())


def hash_password(password: str) -> str:
    return HASHER.hash(password)


def set_password(user: Experimenter, password: str) -> None:
    """A new password ends the account's logins everywhere."""
    user.password_hash = hash_password(password)
    user.session_version = (user.session_version or 0) + 1


def verify_password(password: str, stored: str) -> bool:
    if stored.startswith("scrypt$"):
        return _verify_scrypt(password, stored)
    try:
        return HASHER.verify(stored, password)
    except (VerificationError, InvalidHashError):
        return False


def needs_rehash(stored: str) -> bool:
    """True for hashes made before argon2 (scrypt) or with weaker argon2 parameters than today's."""
    return stored.startswith("scrypt$") or HASHER.check_needs_rehash(stored)


def _verify_scrypt(password: str, stored: str) -> bool:
    """The hashes stored before argon2 (`scrypt$salt$digest`), upgraded at the next login."""
    try:
        _, salt_hex, digest_hex = stored.split("$")
        salt = bytes.fromhex(salt_hex)
    except ValueError:
        return False
    digest = hashlib.scrypt(password.encode(), salt=salt, n=2**14, r=8, p=1)
    return hmac.compare_digest(digest.hex(), digest_hex)

"""`LoginGuard`: experimenter logins, rate-limited and checked off the event loop.

Attempts are counted per client address (an IPv6 client's /64, which one machine is given
whole) and per account name from that address (`app.client_limits`: in Redis when the processes
share one, else in this process's memory); an attempt counts until it succeeds, which clears its
client's count for the account. The guessing client is locked out, never the account: an
attacker's guesses cannot keep the experimenter, at another address, from logging in. Password
hashes are computed in worker threads, at most `concurrency` at once, so a burst of logins queues
instead of taking every thread and hundreds of megabytes of hash memory.
An unknown name is checked against a dummy hash, so it costs what a known one costs.
"""

from __future__ import annotations

import asyncio
import os
import secrets

from limits import parse
from limits.storage import Storage
from sqlalchemy import select
from sqlalchemy.orm import Session, sessionmaker

from app.client_limits import Counts, Limit, Limited, client_key
from app.db.models import Experimenter
from app.security import hash_password, needs_rehash, verify_password


class TooManyAttempts(Exception):
    def __init__(self, retry_after_s: int) -> None:
        super().__init__(f"too many login attempts; try again in {retry_after_s} s")
        self.retry_after_s = retry_after_s


class LoginGuard:
    def __init__(
        self,
        db: sessionmaker[Session],
        per_account: str,
        per_address: str,
        concurrency: int | None = None,
        storage: Storage | None = None,
    ) -> None:
        self._db = db
        self._counts = Counts(storage)
        self._per_account, self._per_address = parse(per_account), parse(per_address)
        self._slots = asyncio.Semaphore(concurrency or len(os.sched_getaffinity(0)))
        self._dummy_hash = hash_password(secrets.token_urlsafe(16))

    async def authenticate(self, name: str, password: str, address: str) -> int | None:
        """The experimenter's id, None for a wrong name or password; raises `TooManyAttempts`."""
        self._count_attempt(name, address)
        async with self._slots:
            user_id = await asyncio.to_thread(self._check, name, password)
        if user_id is not None:
            self._counts.clear(self._account_limit(name, address))
        return user_id

    def _account_limit(self, name: str, address: str) -> Limit:
        return Limit(self._per_account, ("account", name, client_key(address)))

    def _count_attempt(self, name: str, address: str) -> None:
        try:
            self._counts.take(
                self._account_limit(name, address), Limit(self._per_address, ("address", client_key(address)))
            )
        except Limited as err:
            raise TooManyAttempts(err.retry_after_s) from None

    def _check(self, name: str, password: str) -> int | None:
        with self._db.begin() as db:
            user = db.scalar(select(Experimenter).where(Experimenter.name == name))
            if user is None:
                verify_password(password, self._dummy_hash)
                return None
            if not verify_password(password, user.password_hash):
                return None
            if needs_rehash(user.password_hash):  # e.g. an scrypt hash from before argon2
                user.password_hash = hash_password(password)
            return int(user.id)

"""Counts of what a client (or everyone) did in a moving window (`limits`): logins, study sign-ups.

An attempt is tested against all its limits before it is counted against any, so one refused
costs no count: a client retrying while locked out does not lock itself out for longer. The
counts are in Redis when the processes share one (spreading attempts over them gains nothing),
else in this process's memory.
"""

from __future__ import annotations

import ipaddress
import time
from dataclasses import dataclass

from limits import RateLimitItem
from limits.storage import MemoryStorage, RedisStorage, Storage
from limits.strategies import MovingWindowRateLimiter


@dataclass(frozen=True)
class Limit:
    rate: RateLimitItem
    key: tuple[str, ...]  # what it counts: ("address", client), ("account", name, client), ...


class Limited(Exception):
    def __init__(self, retry_after_s: int) -> None:
        super().__init__(f"try again in {retry_after_s} s")
        self.retry_after_s = retry_after_s


class Counts:
    def __init__(self, storage: Storage | None = None) -> None:
        self._limiter = MovingWindowRateLimiter(storage or MemoryStorage())

    def take(self, *limits: Limit) -> None:
        """Count one attempt against every limit; raises `Limited` (counting nothing) when any is spent."""
        for limit in limits:
            if not self._limiter.test(limit.rate, *limit.key):
                reset = self._limiter.get_window_stats(limit.rate, *limit.key).reset_time
                raise Limited(max(1, int(reset - time.time() + 0.999)))
        for limit in limits:
            self._limiter.hit(limit.rate, *limit.key)

    def clear(self, limit: Limit) -> None:
        self._limiter.clear(limit.rate, *limit.key)


def client_key(address: str) -> str:
    """What one client's attempts are counted under: its IPv4 address, or its IPv6 /64."""
    try:
        ip = ipaddress.ip_address(address)
    except ValueError:
        return address
    if isinstance(ip, ipaddress.IPv6Address):
        if ip.ipv4_mapped is not None:
            return str(ip.ipv4_mapped)
        return str(ipaddress.IPv6Network((ip, 64), strict=False))
    return str(ip)


def shared_counts(redis_url: str, key_prefix: str, what: str) -> Storage:
    """The counts of every process on `redis_url` (one round trip per count, on loopback a
    fraction of a millisecond: logins and sign-ups are rare)."""
    return RedisStorage(redis_url, key_prefix=f"{key_prefix}:{what}")

"""How fast a study takes people in: consents and lobby joins, per client address (an IPv6 /64)
and per study (`ROBOTSLANG_STUDY_*_LIMIT_*`, `limits` notation, moving windows; `app.client_limits`).
One address once made 200 participants and 100 lobby trials in 11 s; a lab whose participants
share one address (a NAT) may raise the per-address limits."""

from __future__ import annotations

from enum import StrEnum

from limits import RateLimitItem, parse_many
from limits.storage import Storage

from app.client_limits import Counts, Limit, client_key
from app.settings import Settings


class Step(StrEnum):
    consent = "consent"  # an agreement: a new participant
    lobby = "lobby"  # entering the lobby to be paired: a new trial, once paired


class SignupLimits:
    def __init__(self, settings: Settings, storage: Storage | None = None) -> None:
        self._counts = Counts(storage)
        self._rates: dict[Step, tuple[list[RateLimitItem], list[RateLimitItem]]] = {
            Step.consent: (
                parse_many(settings.study_consent_limit_per_address),
                parse_many(settings.study_consent_limit_per_study),
            ),
            Step.lobby: (
                parse_many(settings.study_lobby_limit_per_address),
                parse_many(settings.study_lobby_limit_per_study),
            ),
        }

    def take(self, step: Step, study: str, address: str) -> None:
        """Count one `step` into `study` from `address`; raises `Limited` (counting nothing) when
        a limit is spent."""
        per_address, per_study = self._rates[step]
        client = client_key(address)
        self._counts.take(
            *(Limit(rate, (step, "address", client)) for rate in per_address),
            *(Limit(rate, (step, "study", study)) for rate in per_study),
        )

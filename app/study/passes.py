"""The participant's pass: a signed cookie naming their study and enrolment, so a participant
needs no account. Another salt than seat and LDH links, so none of them opens another."""

from __future__ import annotations

from dataclasses import dataclass

from itsdangerous import BadSignature, URLSafeTimedSerializer

from app.security import InvalidToken

PASS_COOKIE = "robotslang_study"


@dataclass(frozen=True)
class ParticipantPass:
    study: str
    enrolment_id: int  # StudyParticipant.id


class ParticipantPasses:
    def __init__(self, secret: str) -> None:
        self._serializer = URLSafeTimedSerializer(secret, salt="participant-study")

    def issue(self, study: str, enrolment_id: int) -> str:
        return self._serializer.dumps({"s": study, "p": enrolment_id})

    def verify(self, token: str) -> ParticipantPass:
        try:
            data = self._serializer.loads(token)
            return ParticipantPass(str(data["s"]), int(data["p"]))
        except (BadSignature, KeyError, TypeError, ValueError):
            raise InvalidToken("study pass is not valid (forged or damaged)") from None

"""The participant's pass: a signed cookie naming their study and enrolment, so a participant
needs no account. Another salt than seat and LDH links, so none of them opens another. And the
panel's identifiers a study link carried, kept in a signed cookie of their own from the link's
arrival (the address bar then cleaned of them) until the participant consents."""

from __future__ import annotations

from dataclasses import dataclass

from itsdangerous import BadSignature, URLSafeTimedSerializer

from app.security import InvalidToken
from app.study.config import PanelIds

PASS_COOKIE = "robotslang_study"
PANEL_COOKIE = "robotslang_panel"


@dataclass(frozen=True)
class ParticipantPass:
    study: str
    enrolment_id: int  # StudyParticipant.id


class ParticipantPasses:
    def __init__(self, secret: str) -> None:
        self._serializer = URLSafeTimedSerializer(secret, salt="participant-study")
        self._panel = URLSafeTimedSerializer(secret, salt="participant-panel")

    def issue(self, study: str, enrolment_id: int) -> str:
        return self._serializer.dumps({"s": study, "p": enrolment_id})

    def verify(self, token: str) -> ParticipantPass:
        try:
            data = self._serializer.loads(token)
            return ParticipantPass(str(data["s"]), int(data["p"]))
        except (BadSignature, KeyError, TypeError, ValueError):
            raise InvalidToken("study pass is not valid (forged or damaged)") from None

    def issue_panel(self, study: str, ids: PanelIds) -> str:
        return self._panel.dumps({"s": study, "i": [ids.participant, ids.study, ids.session]})

    def panel_of(self, token: str, study: str) -> PanelIds | None:
        """The panel identifiers a link to `study` carried, from their cookie (None: none, or not valid)."""
        try:
            data = self._panel.loads(token)
            participant, panel_study, session = data["i"]
            return PanelIds(participant, panel_study, session) if data["s"] == study else None
        except (BadSignature, KeyError, TypeError, ValueError):
            return None

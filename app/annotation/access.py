"""The annotator's login: its own cookie and salt (`Sessions` for the annotator role), so that
an annotator's cookie opens only the annotation pages and never an experimenter's."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends
from starlette.requests import HTTPConnection

from app.cookies import read_cookie
from app.deps import AnnotatorSessionsDep, LoginRequired
from app.security import ANNOTATOR_COOKIE, Login


def annotator_login(conn: HTTPConnection, sessions: AnnotatorSessionsDep) -> Login | None:
    if not hasattr(conn.state, "annotator_login"):
        conn.state.annotator_login = sessions.verify(read_cookie(conn, ANNOTATOR_COOKIE))
    login: Login | None = conn.state.annotator_login
    return login


def annotator_id(login: Annotated[Login | None, Depends(annotator_login)]) -> int:
    """The logged-in annotator's id; anyone else is sent to the login page."""
    if login is None:
        raise LoginRequired()
    return login.experimenter_id


AnnotatorId = Annotated[int, Depends(annotator_id)]

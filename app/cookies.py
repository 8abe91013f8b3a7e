"""The server's cookies, set, read and deleted in one way. Over TLS (https or wss, as the socket or
a trusted proxy's X-Forwarded-Proto says) each is named `__Host-NAME` and set Secure for the whole
host: the browser then refuses one sent over plain http or set by another host under the same
domain. Over plain http (a lab's own network) it is NAME. And what the server sends to make a
browser forget everything of this site (`Clear-Site-Data`), on logout and withdrawal."""

from __future__ import annotations

from typing import Literal

from starlette.requests import HTTPConnection
from starlette.responses import RedirectResponse, Response

HOST_PREFIX = "__Host-"
CLEAR_SITE_DATA = '"cache", "cookies", "storage"'


def cookie_name(base: str, scheme: str | None) -> str:
    return HOST_PREFIX + base if scheme in ("https", "wss") else base


def read_cookie(conn: HTTPConnection, base: str) -> str | None:
    return conn.cookies.get(cookie_name(base, conn.url.scheme))


def set_cookie(
    response: Response,
    conn: HTTPConnection,
    base: str,
    value: str,
    samesite: Literal["lax", "strict"] = "lax",
    path: str = "/",
    max_age: int | None = None,
) -> None:
    """An HttpOnly cookie; over TLS `__Host-`, Secure and for the whole host (a `__Host-` cookie's Path is /)."""
    tls = conn.url.scheme == "https"
    response.set_cookie(
        cookie_name(base, conn.url.scheme),
        value,
        max_age=max_age,
        httponly=True,
        samesite=samesite,
        secure=tls,
        path="/" if tls else path,
    )


def delete_cookie(response: Response, conn: HTTPConnection, base: str, path: str = "/") -> None:
    tls = conn.url.scheme == "https"
    response.delete_cookie(cookie_name(base, conn.url.scheme), path="/" if tls else path, secure=tls, httponly=True)


def clear_site_data(response: Response) -> None:
    """The browser forgets this site's cookies, storage and cache (a logout, a withdrawal)."""
    response.headers["Clear-Site-Data"] = CLEAR_SITE_DATA


def logged_out(conn: HTTPConnection, base: str) -> RedirectResponse:
    """Home, with the login's cookie `base` deleted and the browser told to forget the site."""
    response = RedirectResponse("/", status_code=303)
    delete_cookie(response, conn, base)
    clear_site_data(response)
    return response

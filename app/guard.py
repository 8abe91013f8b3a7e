"""The web boundary's checks: the Host header (DNS rebinding), security headers, the Origin of
sockets and of state-changing requests, and the CSRF token those requests carry.

Cookies are shared by every port of a host, and SameSite treats another port of 127.0.0.1 as the
same site, so neither stops a page on another port from posting with the experimenter's cookie:
the Origin check and a token the other page cannot read do.
"""

from __future__ import annotations

import ipaddress
import re
import secrets
from urllib.parse import urlsplit

from fastapi import HTTPException, Request
from starlette.datastructures import Headers, MutableHeaders
from starlette.responses import PlainTextResponse
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from app.cookies import cookie_name
from app.deps import CsrfDep, CurrentLogin, SettingsDep, current_login, get_services
from app.i18n import Text, browser_messages, language_of
from app.settings import Settings

BROWSER_COOKIE = "robotslang_browser"  # a random id per browser, which anonymous CSRF tokens bind to
CSRF_HEADER = "x-csrf-token"
CSRF_FIELD = "csrf_token"
SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})
DEFAULT_PORTS = {"http": 80, "https": 443}
PAGE_SCHEMES = {"ws": "http", "wss": "https", "http": "http", "https": "https"}
_BROWSER_ID = re.compile(r"[A-Za-z0-9_-]{32}")

# Scripts and styles only from /static (no inline code); camera frames arrive as data: URLs.
CONTENT_SECURITY_POLICY = (
    "default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data:; "
    "connect-src 'self'; object-src 'none'; base-uri 'none'; form-action 'self'; "
    "frame-ancestors 'none'"
)
SECURITY_HEADERS = {
    "content-security-policy": CONTENT_SECURITY_POLICY,
    "x-content-type-options": "nosniff",
    # same-origin, not no-referrer: under no-referrer browsers send `Origin: null` with form posts.
    "referrer-policy": "same-origin",
    "x-frame-options": "DENY",
}

Origin = tuple[str, str, int]  # scheme, host, port


def origin_of(url: str) -> Origin | None:
    """(scheme, host, port) of an http(s) URL or Origin header; None for `null` or anything else."""
    parts = urlsplit(url.strip())
    scheme = PAGE_SCHEMES.get(parts.scheme.lower())
    try:
        port = parts.port
    except ValueError:
        return None
    if scheme is None or not parts.hostname:
        return None
    return scheme, parts.hostname.lower(), port or DEFAULT_PORTS[scheme]


def origin_allowed(origin: str, scheme: str, host: str | None, settings: Settings) -> bool:
    """`origin` is this server's own (the request's scheme, Host and port) or an allowed origin."""
    claimed = origin_of(origin)
    if claimed is None:
        return False
    return claimed == origin_of(f"{scheme}://{host or ''}") or claimed in {
        origin_of(o) for o in settings.allowed_origins
    }


def socket_origin_allowed(headers: Headers, scheme: str, settings: Settings) -> bool:
    """Browsers always send Origin on a websocket, which must then be allowed. Clients that are not
    browsers (scripts, the rover) send none and are judged by their token alone."""
    origin = headers.get("origin")
    return origin is None or origin_allowed(origin, scheme, headers.get("host"), settings)


class HostNames:
    """The Host header names served: `allowed_hosts`, the hosts of `allowed_origins`, and any IP
    literal (DNS rebinding needs a name; an address always means the server itself)."""

    def __init__(self, settings: Settings) -> None:
        names = {self._name(h) for h in settings.allowed_hosts}
        names |= {o[1] for o in map(origin_of, settings.allowed_origins) if o}
        self._names = names - {None}
        self._any = "*" in settings.allowed_hosts

    @staticmethod
    def _name(host: str) -> str | None:
        try:
            return urlsplit(f"//{host.strip()}").hostname
        except ValueError:
            return None

    def allows(self, host_header: str) -> bool:
        name = self._name(host_header)
        if name is None:
            return False
        if self._any or name in self._names:
            return True
        try:
            ipaddress.ip_address(name)
            return True
        except ValueError:
            return False


class GuardMiddleware:
    """Refuses a request without exactly one known Host header, adds the security headers to
    every response and gives each browser its id cookie (in `request.state.browser_id`)."""

    def __init__(self, app: ASGIApp, settings: Settings) -> None:
        self.app = app
        self.hosts = HostNames(settings)

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        headers = Headers(scope=scope)
        # Exactly one Host: with two, a proxy and this server could each read another name.
        hosts = headers.getlist("host")
        if len(hosts) != 1 or not self.hosts.allows(hosts[0]):
            if scope["type"] == "websocket":
                await send({"type": "websocket.close", "code": 1008, "reason": "host not allowed"})
            else:
                response = PlainTextResponse(
                    "this server is not served under that host name", 400, headers=SECURITY_HEADERS
                )
                await response(scope, receive, send)
            return
        if scope["type"] == "websocket":
            await self.app(scope, receive, send)
            return
        browser_cookie = cookie_name(BROWSER_COOKIE, scope.get("scheme"))
        browser_id = _cookie(headers, browser_cookie)
        new_browser = browser_id is None or not _BROWSER_ID.fullmatch(browser_id)
        if new_browser:
            browser_id = secrets.token_urlsafe(24)
        scope.setdefault("state", {})["browser_id"] = browser_id
        secure = "; Secure" if scope.get("scheme") == "https" else ""

        async def send_guarded(message: Message) -> None:
            if message["type"] == "http.response.start":
                response_headers = MutableHeaders(scope=message)
                for name, value in SECURITY_HEADERS.items():
                    response_headers[name] = value
                if new_browser:
                    response_headers.append(
                        "set-cookie", f"{browser_cookie}={browser_id}; Path=/; HttpOnly; SameSite=Strict{secure}"
                    )
            await send(message)

        await self.app(scope, receive, send_guarded)


def _cookie(headers: Headers, name: str) -> str | None:
    for part in headers.get("cookie", "").split(";"):
        key, _, value = part.strip().partition("=")
        if key == name:
            return value
    return None


def template_context(request: Request) -> dict[str, object]:
    """Every page's `csrf_token`, for `<meta name="csrf-token">` and its forms' `csrf_token` field,
    and its language (`app.i18n`): `lang` and the translations its scripts use."""
    lang = language_of(request)
    return {
        "csrf_token": get_services(request).csrf.issue(request.state.browser_id, current_login(request)),
        "lang": lang,
        "browser_messages": browser_messages(lang),
    }


async def csrf_protect(request: Request, settings: SettingsDep, csrf: CsrfDep, login: CurrentLogin) -> None:
    """A state-changing request must come from this server's pages: an allowed Origin (or Referer,
    where a browser sends no Origin) and the page's CSRF token, in X-CSRF-Token or the form."""
    if request.method in SAFE_METHODS:
        return
    origin = request.headers.get("origin") or request.headers.get("referer")
    if not origin:
        raise HTTPException(403, "refused: a state-changing request must carry an Origin or Referer header")
    if not origin_allowed(origin, request.url.scheme, request.headers.get("host"), settings):
        raise HTTPException(403, f"refused: a page from {origin[:100]} may not change anything here")
    token: object = request.headers.get(CSRF_HEADER)
    if token is None:
        token = (await request.form()).get(CSRF_FIELD)
    if not isinstance(token, str) or not csrf.verify(token, request.state.browser_id, login):
        raise HTTPException(
            403, Text("refused: the page's security token is missing or stale; reload the page and retry")
        )

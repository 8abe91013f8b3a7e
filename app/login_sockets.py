"""`LoginSockets`: the experimenter sockets open under each login, so a logout closes them at once.

A logout in another process, or a password change from the command line, is seen by each watch
socket's own check of its login (`app.routes.seat_ws`, every `LOGIN_RECHECK_S`).
"""

from __future__ import annotations

import threading
from collections import defaultdict
from typing import Protocol

from app.security import Login


class LoginSocket(Protocol):
    def log_out(self) -> None:
        """Deliver nothing more and close; callable from any thread."""


class LoginSockets:
    def __init__(self) -> None:
        self._open: defaultdict[Login, set[LoginSocket]] = defaultdict(set)
        self._lock = threading.Lock()  # logout runs in a worker thread, the sockets on the event loop

    def add(self, login: Login, socket: LoginSocket) -> None:
        with self._lock:
            self._open[login].add(socket)

    def discard(self, login: Login, socket: LoginSocket) -> None:
        with self._lock:
            sockets = self._open.get(login)
            if sockets is not None:
                sockets.discard(socket)
                if not sockets:
                    del self._open[login]

    def end(self, login: Login) -> None:
        with self._lock:
            sockets = self._open.pop(login, set())
        for socket in sockets:
            socket.log_out()

"""What the server's child processes (render processes, maze builders) share: they end with it."""

from __future__ import annotations

import os
import threading
import time


def follow(server: int) -> None:
    """In a child process: exit once `server`, the pid that started it, is gone. A server killed
    with SIGKILL cannot stop its children, and a process pool's idle worker would wait for work
    forever (`server` may have died before the child got here: then it exits at once)."""
    threading.Thread(target=_exit_with, args=(server,), name="follow-server", daemon=True).start()


def _exit_with(server: int) -> None:
    while os.getppid() == server:
        time.sleep(0.5)
    os._exit(0)

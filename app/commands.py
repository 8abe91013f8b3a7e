"""`robotslang serve|admin|db|export|demo`."""

from __future__ import annotations

import typer


def register(root: typer.Typer) -> None:
    """Mount the server's commands on the root CLI."""

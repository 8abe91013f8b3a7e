"""Where the server's shipped folders are: inside the installed package, else in the checkout.

A wheel ships `templates/`, `static/` and `migrations/` inside `app` (pyproject's package-dir
mapping); a checkout (and an editable install) keeps them at the top of the repository.
"""

from __future__ import annotations

from pathlib import Path

PACKAGE = Path(__file__).resolve().parent


def shipped(name: str) -> Path:
    """The folder `name` ("templates", "static", "migrations") of this installation."""
    for folder in (PACKAGE / name, PACKAGE.parent / name):
        if folder.is_dir():
            return folder
    raise FileNotFoundError(f"{name}/ is neither in {PACKAGE} (a wheel) nor in {PACKAGE.parent} (a checkout)")

"""`robotslang train|eval ndh|report|experiment`: placeholder until the learned Driver lands."""

from __future__ import annotations

import typer


def register(root: typer.Typer, eval_app: typer.Typer) -> None:
    """Mount this package's commands on the root CLI."""

"""Helpers for tests that run the project as a user outside the checkout would."""

from __future__ import annotations

import os
from pathlib import Path

from bench.live import free_port  # noqa: F401  (shared with the tests here)

REPO = Path(__file__).resolve().parents[2]


def clean_env(**extra: str) -> dict[str, str]:
    """This environment without the checkout on PYTHONPATH, this venv or the benchmark, plus `extra`."""
    env = {
        k: v
        for k, v in os.environ.items()
        if k
        not in (
            "PYTHONPATH",
            "VIRTUAL_ENV",
            "ROBOTSLANG_BENCHMARK",
            "ROBOTSLANG_DATA_DIR",
            "ROBOTSLANG_DATABASE_URL",
            "ROBOTSLANG_REDIS_URL",
        )
    }
    return {**env, **extra}

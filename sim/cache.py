"""Where derived per-maze tables are cached on disk."""

from __future__ import annotations

import os
from pathlib import Path


def cache_dir(override: str | Path | None = None) -> Path:
    """`override`, else ROBOTSLANG_CACHE_DIR, else ~/.cache/robotslang."""
    if override is not None:
        return Path(override)
    env = os.environ.get("ROBOTSLANG_CACHE_DIR")
    return Path(env) if env else Path.home() / ".cache" / "robotslang"

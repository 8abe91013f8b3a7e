"""Where derived per-maze tables are cached on disk."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike


def cache_dir(override: str | Path | None = None) -> Path:
    """`override`, else ROBOTSLANG_CACHE_DIR, else ~/.cache/robotslang."""
    if override is not None:
        return Path(override)
    env = os.environ.get("ROBOTSLANG_CACHE_DIR")
    return Path(env) if env else Path.home() / ".cache" / "robotslang"


def save_npz(path: Path, compressed: bool = False, **arrays: ArrayLike) -> None:
    """Write arrays to `path` then rename, so concurrent builders never read a half-written file."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".npz")
    os.close(fd)
    # numpy's stubs let **kwds reach the keyword `allow_pickle: bool`; every key here is an array's name.
    (np.savez_compressed if compressed else np.savez)(tmp, **arrays)  # type: ignore[arg-type]
    os.replace(tmp, path)

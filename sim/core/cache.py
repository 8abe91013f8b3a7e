"""Where derived per-maze tables are cached on disk, and the one file format they use.

An array file (`save_arrays`, `load_arrays`) is a JSON header naming each array's dtype, shape
and place, then the arrays' bytes, whole or zlib-compressed. A trial opening reads its maze,
graph, ray table and render scene from these: one read and a view per array. numpy's `.npz` is
a zip member and a parsed header per array, 27 ms for a maze's four files and 12.5 ms for a
scene's 59 arrays on the 2-core machine, which a crowd of trials opening at once paid in the
render process's queue and in the GIL beside the event loop.
"""

from __future__ import annotations

import json
import os
import struct
import tempfile
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike
from zlib_ng import zlib_ng as zlib  # zlib's format, 3 to 9 times faster to write and to read

ARRAYS_SUFFIX = ".arrays"
_MAGIC = b"RSARRAY1"
_ALIGN = 64  # each array starts on a cache line


def cache_dir(override: str | Path | None = None) -> Path:
    """`override`, else ROBOTSLANG_CACHE_DIR, else ~/.cache/robotslang."""
    if override is not None:
        return Path(override)
    env = os.environ.get("ROBOTSLANG_CACHE_DIR")
    return Path(env) if env else Path.home() / ".cache" / "robotslang"


def save_arrays(path: Path, compressed: bool = False, **arrays: ArrayLike) -> None:
    """Write arrays to `path` then rename, so concurrent builders never read a half-written file.
    `compressed` for tables that are mostly one value (label grids): smaller, slower to read."""
    entries, chunks, offset = [], [], 0
    for name, value in arrays.items():
        a = np.asarray(value)  # not ascontiguousarray: it makes a 0-d array 1-d
        if a.dtype.hasobject:
            raise ValueError(f"{name}: an array of Python objects cannot be cached")
        pad = -offset % _ALIGN
        chunks.append(bytes(pad))
        offset += pad
        entries.append({"name": name, "dtype": a.dtype.str, "shape": list(a.shape), "offset": offset})
        chunks.append(a.tobytes(order="C"))
        offset += a.nbytes
    body = b"".join(chunks)
    header = json.dumps({"arrays": entries, "zlib": compressed, "size": len(body)}).encode()
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=ARRAYS_SUFFIX)
    with os.fdopen(fd, "wb") as f:
        f.write(_MAGIC + struct.pack("<I", len(header)) + header)
        f.write(zlib.compress(body, 1) if compressed else body)
    os.replace(tmp, path)


def load_arrays(path: Path) -> dict[str, np.ndarray]:
    """The arrays `save_arrays` wrote, each its own writable array (one that is let go frees its
    memory: a graph drops its all-pairs tables once a trial has its start). Raises OSError when
    there is no file, ValueError when it is torn or not an array file (the caller builds it again)."""
    data = path.read_bytes()
    start = len(_MAGIC) + 4
    if len(data) < start or data[: len(_MAGIC)] != _MAGIC:
        raise ValueError(f"{path}: not an array file")
    (length,) = struct.unpack_from("<I", data, len(_MAGIC))
    raw = memoryview(data)[start + length :]
    try:
        header = json.loads(data[start : start + length])
        body = memoryview(zlib.decompress(raw)) if header["zlib"] else raw
    except (json.JSONDecodeError, zlib.error) as err:  # type: ignore[misc]  # zlib-ng's stub: an instance
        raise ValueError(f"{path}: torn") from err
    if len(body) != header["size"]:
        raise ValueError(f"{path}: torn ({len(body)} of {header['size']} bytes)")
    return {
        e["name"]: np.frombuffer(body, np.dtype(e["dtype"]), int(np.prod(e["shape"], dtype=np.int64)), e["offset"])
        .reshape(e["shape"])
        .copy()
        for e in header["arrays"]
    }

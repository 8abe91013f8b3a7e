"""Physical layouts: mazes that are the same tabletop under different names.

The benchmark recorded several runs on one physical maze (Run_114, Run_117, Run_119, Run_124 and
Run_130 are one), with the landmarks put back a centimetre or two apart and the walls redrawn
with other thicknesses. Two mazes are one layout when every landmark lies within
`LANDMARK_TOLERANCE_M` (9 cm) of its counterpart and nearly every wall cell of each lies within
`WALL_TOLERANCE_M` of a wall of the other; layouts are the groups this links (transitively).
Mazes with the same walls and landmarks placed elsewhere are different layouts: the task
differs.

A maze's signature (its landmarks and a 1 cm wall grid with each cell's distance to the
nearest wall) is cached per maze like its graph; a library's grouping is cached keyed on its
maze names and map files, so a process that has it decodes no map.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, fields
from pathlib import Path
from typing import TypedDict

import cv2
import numpy as np
from numpy.typing import NDArray

from sim.core.cache import ARRAYS_SUFFIX, load_arrays, save_arrays
from sim.core.cache import cache_dir as default_cache_dir
from sim.core.geometry import TABLE_WIDTH_M
from sim.core.labels import OBJECTS, Label
from sim.core.maze import Maze

# A landmark put back on the same table overlaps its old footprint (a 9 cm disc on the map): runs
# with identical walls have landmarks up to 6.0 cm apart (Run_363/Run_364), Run_114's five runs up
# to 3.2 cm; the next identical-wall pair is 10.5 cm apart (Run_225/Run_226).
LANDMARK_TOLERANCE_M = 0.09
# Walls drawn 1-3 cm thicker or thinner on the same table still match; a wall moved or added
WALL_TOLERANCE_M = 0.04
WALL_MISMATCH_MAX = 0.02
CELL_PX = 6  # a wall grid cell: 6 map pixels, about 1.05 cm
_SIGNATURE_VERSION = 2  # 2: keyed by the map files (1: by the maze's contents)
_GROUPING_VERSION = 1


@dataclass(frozen=True, eq=False)
class LayoutSignature:
    landmarks: NDArray[np.float64]  # (3, 2) metres, in OBJECTS order
    walls: NDArray[np.bool_]  # (h, w) cells holding any wall pixel
    distance_m: NDArray[np.float32]  # (h, w) each cell's distance to the nearest wall cell

    @classmethod
    def of(cls, maze: Maze) -> LayoutSignature:
        landmarks = np.array([maze.objects[w] for w in OBJECTS], dtype=np.float64)
        wall_px = (maze.walls != Label.FLOOR).astype(np.uint8)
        h, w = wall_px.shape[0] // CELL_PX, wall_px.shape[1] // CELL_PX
        # A cell's rows reduced first, then its columns as strided slices: numpy's reduction over a
        # block's short inner axes took 4.5 ms a maze, these 0.2 ms.
        rows = wall_px[: h * CELL_PX, : w * CELL_PX].reshape(h, CELL_PX, w * CELL_PX).max(axis=1)
        walls = np.logical_or.reduce([rows[:, k::CELL_PX] for k in range(CELL_PX)])
        cell_m = TABLE_WIDTH_M / (maze.walls.shape[1] - 1) * CELL_PX
        free = np.where(walls, 0, 255).astype(np.uint8)
        distance = cv2.distanceTransform(free, cv2.DIST_L2, cv2.DIST_MASK_PRECISE).astype(np.float32) * cell_m
        return cls(landmarks=landmarks, walls=walls, distance_m=distance)

    @classmethod
    def cached(cls, key: str, maze: Callable[[], Maze], cache_dir: str | Path | None = None) -> LayoutSignature:
        """The signature of the maze whose map files have `key` (`MazeLibrary.maps_key`): read from
        the cache, else made of `maze()` and stored. Keyed by the files, not by the maze's contents,
        so that reading it loads no maze: grouping a prepared library of 200 mazes loaded each one's
        grids in the server's warm-up thread (3-4 s of that thread in a profile)."""
        path = default_cache_dir(cache_dir) / "layouts" / f"{key}-v{_SIGNATURE_VERSION}{ARRAYS_SUFFIX}"
        if path.exists():
            try:
                data = load_arrays(path)
                return cls(**{f.name: data[f.name] for f in fields(cls)})
            except (OSError, ValueError, KeyError):
                pass  # a torn or stale cache file is rebuilt below
        signature = cls.of(maze())
        save_arrays(path, compressed=True, **{f.name: getattr(signature, f.name) for f in fields(signature)})
        return signature

    def wall_mismatch(self, other: LayoutSignature) -> float:
        """The larger fraction, of either maze's wall cells, farther than the tolerance from the
        other's walls (1.0 for grids of different sizes)."""
        if self.walls.shape != other.walls.shape:
            return 1.0
        mine = _fraction_far(self.walls, other.distance_m)
        theirs = _fraction_far(other.walls, self.distance_m)
        return max(mine, theirs)


def _fraction_far(walls: NDArray[np.bool_], distance_m: NDArray[np.float32]) -> float:
    count = int(walls.sum())
    return float((distance_m[walls] > WALL_TOLERANCE_M).sum()) / count if count else 0.0


class LayoutRow(TypedDict):
    id: str
    runs: list[str]


@dataclass(frozen=True)
class Layout:
    id: str  # the name of its first maze, in the order given
    runs: tuple[str, ...]

    def as_json(self) -> LayoutRow:
        return {"id": self.id, "runs": list(self.runs)}


def group_layouts(signatures: Mapping[str, LayoutSignature]) -> list[Layout]:
    """The mazes, by name, grouped into layouts, in the mapping's order (each layout's runs too).
    Walls are compared only for pairs whose landmarks match (a few per maze)."""
    names = list(signatures)
    if not names:
        return []
    landmarks = np.stack([signatures[n].landmarks for n in names])
    shift = np.linalg.norm(landmarks[:, None] - landmarks[None], axis=-1).max(axis=-1)
    parent = list(range(len(names)))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i, j in zip(*np.nonzero(np.triu(shift <= LANDMARK_TOLERANCE_M, k=1)), strict=True):
        if signatures[names[i]].wall_mismatch(signatures[names[j]]) <= WALL_MISMATCH_MAX:
            a, b = root(int(i)), root(int(j))
            parent[max(a, b)] = min(a, b)  # the earlier maze stays the root: it names the layout
    groups: dict[int, list[str]] = {}
    for i, name in enumerate(names):
        groups.setdefault(root(i), []).append(name)
    return [Layout(id=runs[0], runs=tuple(runs)) for runs in groups.values()]


def layout_of(layouts: Sequence[Layout]) -> dict[str, str]:
    """Each maze name -> the id of its layout."""
    return {run: layout.id for layout in layouts for run in layout.runs}


def grouping_key(maps: Mapping[str, Sequence[Path]]) -> str:
    """A grouping's cache key: the maze names and the bytes of their map files, in order."""
    h = hashlib.sha256(f"v{_GROUPING_VERSION} {LANDMARK_TOLERANCE_M} {WALL_TOLERANCE_M} {WALL_MISMATCH_MAX}".encode())
    for name, files in maps.items():
        h.update(b"\0" + name.encode())
        for file in files:
            h.update(b"\1" + file.read_bytes())
    return h.hexdigest()[:16]


def stored_grouping(key: str, cache_dir: str | Path | None = None) -> list[Layout] | None:
    """The grouping stored under `key`; None where there is none (or a torn or stale one)."""
    try:
        stored = json.loads(_grouping_path(key, cache_dir).read_text())
        return [Layout(id=str(g["id"]), runs=tuple(str(r) for r in g["runs"])) for g in stored["layouts"]]
    except (OSError, ValueError, KeyError, TypeError):
        return None


def cached_grouping(key: str, build: Callable[[], list[Layout]], cache_dir: str | Path | None = None) -> list[Layout]:
    """The grouping stored under `key`, else `build()` (a list of layouts) stored there."""
    stored = stored_grouping(key, cache_dir)
    if stored is not None:
        return stored
    layouts = build()
    path = _grouping_path(key, cache_dir)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".json")
    with os.fdopen(fd, "w") as f:
        json.dump({"layouts": [layout.as_json() for layout in layouts]}, f)
    os.replace(tmp, path)
    return layouts


def _grouping_path(key: str, cache_dir: str | Path | None) -> Path:
    return default_cache_dir(cache_dir) / "layouts" / f"grouping-{key}.json"


class FoldCount(TypedDict):
    """One split's counts (a row of `mazes folds --json` and of benchmark.json's folds)."""

    split: str
    instances: int
    runs: int
    layouts: int
    shared_layouts: int  # its layouts that another split also holds (under any run's name)


def fold_counts(splits: Mapping[str, Sequence[str]], layout_of: Mapping[str, str]) -> list[FoldCount]:
    """Per split (split -> the run of each instance): instances, runs, layouts and the layouts it
    shares with another split. A run missing from `layout_of` is a layout of its own."""
    layouts = {split: {layout_of.get(run, run) for run in runs} for split, runs in splits.items()}
    counts: list[FoldCount] = []
    for split, runs in splits.items():
        others = set().union(*(ls for s, ls in layouts.items() if s != split))
        counts.append(
            {
                "split": split,
                "instances": len(runs),
                "runs": len(set(runs)),
                "layouts": len(layouts[split]),
                "shared_layouts": len(layouts[split] & others),
            }
        )
    return counts

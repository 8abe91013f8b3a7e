"""`World`: mazes compiled into one global node space, the tables the simulator core reads.

Maze k's node i is global node `offset[k] + i`, and a pose is the slot `8 * node + heading`.
From the graphs' forward tables the world compiles the move rules over the whole node space
(`moves`, a `sim.core.moves.Moves`: per slot and action the slot reached, the metres moved and
whether it was a collision), so that a step of a whole batch is one look-up
(`sim.core.stepper.BatchStepper`).

`World.compile` builds one in memory from (name, maze, graph) triples; `World.build` builds
the benchmark's runs with a disk cache keyed on the map files' bytes (reading them is much
cheaper than decoding them), memory-mapped when warm, so a warm process decodes no PNG and
builds no graph.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import ArrayLike, DTypeLike

from sim.core.cache import cache_dir as default_cache_dir
from sim.core.geometry import HEADINGS
from sim.core.moves import Moves

if TYPE_CHECKING:
    from sim.core.maze import Maze
    from sim.core.navgraph import NavGraph
    from sim.core.observations import RayTable

# 4: names, observations optional, derived tables; 5: the fused moves table; 6: int64 moves;
# 7: only the moves table (`Moves`) is derived
_WORLD_VERSION = 7
_ARRAYS = ("offset", "size", "xy", "ij", "forward")
_MOVES = ("moves", "move_lengths")  # `moves.table` and `moves.lengths`, cached too: a warm process reads them


class MazeRuns(Protocol):
    """Where `World.build` reads its runs: the benchmark clone (`sim.tasks.benchmark.Benchmark`)."""

    @property
    def root(self) -> Path: ...

    @property
    def cache_dir(self) -> str | Path | None: ...

    def maze(self, run: str) -> Maze: ...

    def graph(self, run: str, mode: str = "benchmark") -> NavGraph: ...


@dataclass(frozen=True, eq=False)
class World:
    names: tuple[str, ...]  # the mazes, in order
    offset: np.ndarray  # (R,) first global node of each maze
    size: np.ndarray  # (R,) nodes per maze
    xy: np.ndarray  # (G, 2) node positions, metres
    ij: np.ndarray  # (G, 2) grid indices
    forward: np.ndarray  # (G, 8) global node after a forward move, -1 = collision
    obs: np.ndarray | None = None  # (G * 8, F) ray features of slot 8 g + k; None: not compiled
    key: str = ""  # names the cache entry (maze contents and graph mode); "" when not cached

    # -- construction -------------------------------------------------------------
    @classmethod
    def compile(
        cls,
        items: Sequence[tuple[str, Maze, NavGraph]],
        observations: bool = True,
        obs_dtype: DTypeLike = np.float32,
        cache_dir: str | Path | None = None,
        rays: Sequence[RayTable] | None = None,
    ) -> World:
        """(name, maze, graph) triples in one world; ray tables given (`rays`, one per item) or
        from the maze's cache."""
        from sim.core.observations import RayTable  # only when observations are compiled

        parts: dict[str, list[np.ndarray]] = {"xy": [], "ij": [], "forward": [], "obs": []}
        offset, size, total = [], [], 0
        for k, (_, maze, graph) in enumerate(items):
            offset.append(total)
            size.append(graph.n)
            parts["xy"].append(graph.nodes)
            parts["ij"].append(graph.node_ij.astype(np.int64))
            parts["forward"].append(np.where(graph.forward >= 0, graph.forward + total, -1).astype(np.int64))
            if observations:
                table = rays[k] if rays is not None else RayTable.build(maze, graph, cache_dir=cache_dir)
                parts["obs"].append(table.features().reshape(graph.n * HEADINGS, -1).astype(obs_dtype))
            total += graph.n
        if not items:
            raise ValueError("a world needs at least one maze")
        return cls(
            names=tuple(name for name, _, _ in items),
            offset=np.array(offset, dtype=np.int64),
            size=np.array(size, dtype=np.int64),
            xy=np.concatenate(parts["xy"]),
            ij=np.concatenate(parts["ij"]),
            forward=np.concatenate(parts["forward"]),
            obs=np.concatenate(parts["obs"]) if observations else None,
        )

    @classmethod
    def build(
        cls,
        bench: MazeRuns,
        runs: Sequence[str],
        cache_dir: str | Path | None = None,
        mode: str = "benchmark",
        observations: bool = True,
        progress: bool = True,
    ) -> World:
        """The benchmark's `runs`, cached on disk by map contents and mode. Observations are
        float16 (half the memory; the learner's input), compiled on first request."""
        key = hashlib.sha256()
        for run in runs:
            key.update(run.encode())
            for png in sorted((bench.root / "mazedata" / run / "maze").glob("maze.map*.png")):
                key.update(png.read_bytes())
        key.update(f"{mode}-v{_WORLD_VERSION}".encode())
        folder = default_cache_dir(cache_dir) / "world" / key.hexdigest()[:16]
        world = cls._load(folder, observations)
        if world is not None:
            return world
        from tqdm import tqdm

        items = [
            (run, bench.maze(run), bench.graph(run, mode))
            for run in tqdm(runs, desc="mazes: graphs", unit="maze", disable=not progress)
        ]
        world = cls.compile(
            items,
            observations=observations,
            obs_dtype=np.float16,
            cache_dir=cache_dir if cache_dir is not None else bench.cache_dir,
        )
        world = cls(**{**world.__dict__, "key": folder.name})
        world._save(folder)
        return world

    @classmethod
    def _load(cls, folder: Path, observations: bool) -> World | None:
        if not (folder / "names.json").exists() or (observations and not (folder / "obs.npy").exists()):
            return None
        try:
            # Memory-mapped: instant to open, and parallel processes share one copy.
            arrays = {k: np.load(folder / f"{k}.npy", mmap_mode="r") for k in _ARRAYS}
            obs = np.load(folder / "obs.npy", mmap_mode="r") if observations else None
            world = cls(
                names=tuple(json.loads((folder / "names.json").read_text())), obs=obs, key=folder.name, **arrays
            )
            table, lengths = (np.load(folder / f"{k}.npy", mmap_mode="r") for k in _MOVES)
            world.__dict__["moves"] = Moves(world.xy, table, lengths)  # filling the cached property
            return world
        except (OSError, ValueError):
            return None  # torn or stale: rebuilt

    def _save(self, folder: Path) -> None:
        # Written beside, then renamed into place, so a reader never sees half a world. A world
        # with observations replaces one without.
        folder.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(dir=folder.parent))
        for k in _ARRAYS + (("obs",) if self.obs is not None else ()):
            np.save(tmp / f"{k}.npy", getattr(self, k))
        for k, table in zip(_MOVES, (self.moves.table, self.moves.lengths)):
            np.save(tmp / f"{k}.npy", table)
        (tmp / "names.json").write_text(json.dumps(list(self.names)))
        if self.obs is not None and folder.exists():
            shutil.rmtree(folder, ignore_errors=True)
        try:
            os.replace(tmp, folder)
        except OSError:  # another process saved it first
            shutil.rmtree(tmp, ignore_errors=True)

    # -- tables -------------------------------------------------------------------
    @property
    def nodes(self) -> int:
        return int(self.offset[-1] + self.size[-1])

    @property
    def obs_features(self) -> int:
        if self.obs is None:
            raise ValueError("this world was compiled without observations")
        return int(self.obs.shape[1])

    def index(self, name: str) -> int:
        try:
            return self._index[name]
        except KeyError:
            raise ValueError(f"maze {name!r} is not in this world") from None

    @cached_property
    def _index(self) -> dict[str, int]:
        return {name: k for k, name in enumerate(self.names)}

    @cached_property
    def moves(self) -> Moves:
        """The move rules over every slot of the world."""
        return Moves.compile(np.asarray(self.xy), np.asarray(self.forward))


def goal_rows(graph: NavGraph, goals: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Distance (K, N) and next hop (K, N) toward each goal node from every node of `graph`."""
    goals = np.asarray(goals, dtype=np.int64)
    # Columns, not the transposed rows: Dijkstra's sums differ in the last bit.
    return graph.dist[:, goals].T, graph.next_hop[:, goals].T.astype(np.int64)

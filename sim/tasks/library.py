"""`MazeLibrary`: every maze the platform can run, by name.

The bundled generated mazes (`gen-000` ...) come first, so a fresh machine has content without
the benchmark; then mazes from extra folders (for instance `robotslang mazes generate` output);
then the benchmark's runs that have a map (`Run_318` ...). Bundled and extra mazes are checked
strictly when loaded (their objects must reach each other); benchmark maps are taken as
published, since one of them (Run_320) fails that check and the paper's figures include it.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from pathlib import Path
from threading import Event
from typing import Protocol

from sim.core.maze import FIXED_MAP, WALLS_MAP, Maze, map_files, maps_key
from sim.core.validation import check_reachable
from sim.tasks.layouts import Layout, LayoutSignature, cached_grouping, group_layouts, grouping_key, stored_grouping

BUNDLED_DIR = Path(__file__).resolve().parent / "mazes"
MANIFEST = "manifest.json"


class UnknownMazeError(KeyError):
    """A maze name the library does not hold."""

    def __str__(self) -> str:  # KeyError would quote the whole message
        return str(self.args[0])


class MazeLibrary:
    def __init__(
        self,
        benchmark: Path | None = None,
        extra_dirs: Iterable[Path] = (),
        bundled: Path | None = BUNDLED_DIR,
        cache: bool = True,
        cache_dir: Path | None = None,
    ) -> None:
        """`benchmark`: a clone of the benchmark (its `mazedata/` is read); `extra_dirs`: folders
        of mazes in the benchmark's layout (`NAME/maze/maze.map-fixed.png`); `cache_dir`: where
        decoded maps are cached (default `sim.core.cache.cache_dir()`)."""
        self.cache_dir = cache_dir
        self._roots: list[tuple[str, Path]] = []
        if bundled is not None:
            self._roots.append(("bundled", Path(bundled)))
        self._roots += [("local", Path(d)) for d in extra_dirs]
        if benchmark is not None:
            benchmark = Path(benchmark)
            if not benchmark.is_dir():
                raise FileNotFoundError(
                    f"{benchmark}: no such folder; expected a clone of the "
                    f"RobotSlang benchmark (with mazedata/Run_*/maze/)"
                )
            mazedata = benchmark / "mazedata"
            self._roots.append(("benchmark", mazedata if mazedata.is_dir() else benchmark))
        self._index: dict[str, tuple[str, Path]] | None = None
        self._cache: dict[str, Maze] | None = {} if cache else None  # None: the caller keeps what it needs

    def _entries(self) -> dict[str, tuple[str, Path]]:
        if self._index is None:
            index: dict[str, tuple[str, Path]] = {}
            for kind, root in self._roots:
                if not root.is_dir():
                    continue
                runs = [d for d in root.iterdir() if (d / "maze" / FIXED_MAP).is_file()]
                for run in sorted(runs, key=_natural_key):
                    index.setdefault(run.name, (kind, run))  # an earlier source shadows a later one
            self._index = index
        return self._index

    def names(self) -> list[str]:
        """All maze names: bundled first, then extra folders, then the benchmark's runs."""
        return list(self._entries())

    def __len__(self) -> int:
        return len(self._entries())

    def _entry(self, name: str) -> tuple[str, Path]:
        try:
            return self._entries()[name]
        except KeyError:
            known = self.names()
            sample = ", ".join(known[:5]) + (", ..." if len(known) > 5 else "")
            where = ", ".join(f"{kind} {root}" for kind, root in self._roots) or "no folders"
            raise UnknownMazeError(
                f"unknown maze {name!r}: the library ({where}) holds {len(known)} mazes: {sample}"
            ) from None

    def source(self, name: str) -> str:
        """Where the maze comes from: 'bundled', 'local' (an extra folder) or 'benchmark'."""
        return self._entry(name)[0]

    def path(self, name: str) -> Path:
        """The maze's folder, in the benchmark's layout."""
        return self._entry(name)[1]

    def load(self, name: str) -> Maze:
        """The maze called `name` (read once per library, unless made with `cache=False`); MazeError
        if its map is malformed."""
        if self._cache is not None and name in self._cache:
            return self._cache[name]
        kind, run = self._entry(name)
        maze = Maze.from_dir(run, name=name, cache_dir=self.cache_dir)
        if kind != "benchmark":
            check_reachable(maze, source=str(run / "maze" / FIXED_MAP))
        if self._cache is not None:
            self._cache[name] = maze
        return maze

    def maps_key(self, name: str) -> str:
        """The key of the maze's map files by their bytes (`sim.core.maze.maps_key`): it changes
        with them, and costs a read and a hash, no decoding."""
        return maps_key(*map_files(self.path(name)))

    def layouts(
        self, cache_dir: str | Path | None = None, stop: Event | None = None, preparing: Preparing | None = None
    ) -> list[Layout]:
        """Every maze grouped by physical layout (`sim.tasks.layouts`), in library order. Cached keyed on
        the map files: after the first call (about 0.2 s a maze), no map is decoded. Raises
        `LayoutsStopped` once `stop` is set, between two maps (each map's signature is kept).
        `preparing`: the mazes it has in hand are read last, once it has cached their maps and
        signatures, rather than decoded twice at once."""
        maps = self._maps()

        def build() -> list[Layout]:
            signatures = {}
            later = []
            for name in maps:
                if preparing is not None and preparing.in_hand(name):
                    later.append(name)
                    continue
                signatures[name] = self._signature(name, cache_dir, stop)
            for name in later:
                assert preparing is not None  # nothing is put off without it
                preparing.ensure(name)
                signatures[name] = self._signature(name, cache_dir, stop)
            return group_layouts({name: signatures[name] for name in maps})

        return cached_grouping(grouping_key(maps), build, cache_dir)

    def stored_layouts(self, cache_dir: str | Path | None = None) -> list[Layout] | None:
        """`layouts()` where the grouping of these very maps is cached; else None, decoding nothing."""
        return stored_grouping(grouping_key(self._maps()), cache_dir)

    def _maps(self) -> dict[str, list[Path]]:
        return {
            name: [f for f in (self.path(name) / "maze" / m for m in (FIXED_MAP, WALLS_MAP)) if f.is_file()]
            for name in self.names()
        }

    def signature(self, name: str, cache_dir: str | Path | None = None) -> LayoutSignature:
        """Maze `name`'s layout signature, cached by its map files: once cached, reading it decodes
        and loads nothing."""
        return LayoutSignature.cached(
            self.maps_key(name), lambda: Maze.from_dir(self.path(name), name=name, cache_dir=cache_dir), cache_dir
        )

    def _signature(self, name: str, cache_dir: str | Path | None, stop: Event | None) -> LayoutSignature:
        if stop is not None and stop.is_set():
            raise LayoutsStopped(f"stopped before {name}")
        return self.signature(name, cache_dir)


class Preparing(Protocol):
    """What prepares mazes into the cache, their decoded maps and layout signatures among what
    it caches (`app.preparation.Preparation`)."""

    def in_hand(self, name: str) -> bool:
        """Whether maze `name` is being prepared, or waits to be, ahead of the library."""

    def ensure(self, name: str) -> None:
        """Return once maze `name` is prepared."""


class LayoutsStopped(Exception):
    """`MazeLibrary.layouts` was asked to stop before it had read every map."""


def _natural_key(path: Path) -> list[int | str]:
    """Run_9 before Run_10; gen-002 before gen-010."""
    return [int(part) if part.isdigit() else part for part in re.split(r"(\d+)", path.name)]

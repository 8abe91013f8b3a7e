"""The benchmark compiled into arrays for batched NDH episodes.

A `World` holds every maze used by the splits in one global node space: the forward-move table,
node positions and grid indices, and the ray observation of each (node, heading). An
`EpisodeSet` holds one split's instances: token ids, start pose, goal node, and per instance
the distance and next hop toward its goal from every node of its maze (what the teacher and
the metrics need), so a whole batch steps in a few numpy calls.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm import tqdm

from sim.benchmark import Benchmark, NDHInstance, episode_start, goal_node
from sim.cache import cache_dir as default_cache_dir
from sim.dynamics import Action, actions_toward
from sim.geometry import HEADINGS
from sim.labels import object_label
from models.tokenizer import Tokenizer

_WORLD_VERSION = 2
_ARRAYS = ("offset", "size", "xy", "ij", "forward", "obs")


@dataclass
class World:
    runs: list[str]
    offset: np.ndarray  # (R,) first global node of each run's graph
    size: np.ndarray  # (R,) nodes per run
    xy: np.ndarray  # (G, 2) node positions, metres
    ij: np.ndarray  # (G, 2) grid indices
    forward: np.ndarray  # (G, 8) global node after a forward move, -1 = collision
    obs: np.ndarray  # (G * 8, F) float16 ray features of node g at heading k in row 8 g + k
    key: str = ""  # identifies the compiled mazes (their contents and the graph mode)

    @property
    def obs_features(self) -> int:
        return self.obs.shape[1]

    def run_index(self, run: str) -> int:
        return self.runs.index(run)

    @classmethod
    def build(cls, bench: Benchmark, runs: list[str], cache_dir: str | Path | None = None,
              mode: str = "benchmark") -> "World":
        """Graphs and ray tables of `runs`, cached on disk by maze contents and mode."""
        from sim.observations import RayTable  # numpy-heavy; only needed when compiling

        key = hashlib.sha256()
        for run in runs:  # the map files' bytes: reading them is much cheaper than decoding
            key.update(run.encode())
            for png in sorted((bench.root / "mazedata" / run / "maze").glob("maze.map*.png")):
                key.update(png.read_bytes())
        key.update(f"{mode}-v{_WORLD_VERSION}".encode())
        folder = default_cache_dir(cache_dir) / "ndh" / f"world-{key.hexdigest()[:16]}"
        if (folder / "runs.json").exists():
            try:
                # Memory-mapped: instant to open, and parallel trainings share one copy.
                return cls(runs=json.loads((folder / "runs.json").read_text()), key=folder.name,
                           **{k: np.load(folder / f"{k}.npy", mmap_mode="r") for k in _ARRAYS})
            except (OSError, ValueError):
                pass  # torn or stale: rebuilt below
        parts = {"xy": [], "ij": [], "forward": [], "obs": []}
        offset, size, total = [], [], 0
        for run in tqdm(runs, desc="mazes: graphs and rays", unit="maze"):
            graph = bench.graph(run, mode)
            rays = RayTable.build(bench.maze(run), graph, cache_dir=cache_dir).features()
            offset.append(total)
            size.append(graph.n)
            parts["xy"].append(graph.nodes)
            parts["ij"].append(graph.node_ij)
            parts["forward"].append(np.where(graph.forward >= 0, graph.forward + total, -1))
            parts["obs"].append(rays.reshape(graph.n * HEADINGS, -1).astype(np.float16))
            total += graph.n
        world = cls(runs=list(runs), key=folder.name, offset=np.array(offset, dtype=np.int64),
                    size=np.array(size, dtype=np.int64),
                    **{k: np.concatenate(v) for k, v in parts.items()})
        world._save(folder)
        return world

    def _save(self, folder: Path) -> None:
        # Written beside, then renamed into place, so a reader never sees half a world.
        folder.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(dir=folder.parent))
        for k in _ARRAYS:
            np.save(tmp / f"{k}.npy", getattr(self, k))
        (tmp / "runs.json").write_text(json.dumps(self.runs))
        try:
            os.replace(tmp, folder)
        except OSError:  # another process saved it first
            shutil.rmtree(tmp, ignore_errors=True)

    def observe(self, node: np.ndarray, heading: np.ndarray) -> np.ndarray:
        """(B,) global nodes and headings -> (B, F) float32 features."""
        return self.obs[node * HEADINGS + heading].astype(np.float32)


@dataclass
class EpisodeSet:
    split: str
    instances: list[NDHInstance]
    tokens: np.ndarray  # (M, T) int64 ids, 0-padded
    lengths: np.ndarray  # (M,)
    run: np.ndarray  # (M,) index into World.runs
    start_node: np.ndarray  # (M,) global
    start_heading: np.ndarray  # (M,)
    goal_node: np.ndarray  # (M,) global
    goal_dist: np.ndarray  # (M, Nmax) shortest-path metres to the goal from each local node
    goal_next: np.ndarray  # (M, Nmax) next local node toward the goal; -1 where no path
    target_label: np.ndarray  # (M,) sim.labels.Label of the target object

    def __len__(self) -> int:
        return len(self.instances)

    @classmethod
    def build(cls, bench: Benchmark, world: World, split: str, tokenizer: Tokenizer,
              mode: str = "benchmark", instances: list[NDHInstance] | None = None) -> "EpisodeSet":
        instances = bench.split(split) if instances is None else instances
        m = len(instances)
        ids = [tokenizer.encode(inst.dialog, inst.target) for inst in instances]
        tokens = np.zeros((m, max(map(len, ids))), dtype=np.int64)
        for k, row in enumerate(ids):
            tokens[k, :len(row)] = row
        geometry = episode_geometry(bench, world, instances, mode)
        target_label = np.array([int(object_label(inst.target)) for inst in instances], dtype=np.int64)
        return cls(split, instances, tokens, np.array([len(r) for r in ids]), **geometry,
                   target_label=target_label)


def episode_geometry(bench: Benchmark, world: World, instances: list[NDHInstance],
                     mode: str = "benchmark") -> dict[str, np.ndarray]:
    """Start pose, goal node, and distance and next hop toward the goal from every node, per
    instance; cached on disk (the start protocol walks the teacher, and graphs are large)."""
    key = hashlib.sha256(f"{world.key}:{mode}:{[(i.run, i.scan, i.inst_idx) for i in instances]}".encode())
    path = default_cache_dir(bench.cache_dir) / "ndh" / f"episodes-{key.hexdigest()[:16]}.npz"
    fields = ("run", "start_node", "start_heading", "goal_node", "goal_dist", "goal_next")
    if world.key and path.exists():
        try:
            with np.load(path) as data:
                return {f: data[f] for f in fields}
        except (OSError, ValueError, KeyError):
            pass  # torn or stale: recomputed below
    m, nmax = len(instances), int(world.size.max())
    out = {f: np.zeros(m, dtype=np.int64) for f in fields[:4]}
    out["goal_dist"] = np.full((m, nmax), np.inf, dtype=np.float64)
    out["goal_next"] = np.full((m, nmax), -1, dtype=np.int64)
    for k, inst in enumerate(instances):
        graph = bench.graph(inst.run, mode)
        r = world.run_index(inst.run)
        off = world.offset[r]
        start = episode_start(graph, inst)
        g = goal_node(graph, inst)
        out["run"][k], out["start_node"][k], out["start_heading"][k] = r, off + start.node, start.heading
        out["goal_node"][k] = off + g
        out["goal_dist"][k, :graph.n] = graph.dist[:, g]
        out["goal_next"][k, :graph.n] = graph.next_hop[:, g]
    if world.key:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".npz")
        os.close(fd)
        np.savez(tmp, **out)
        os.replace(tmp, path)
    return out


def teacher_actions(world: World, episodes: EpisodeSet, idx: np.ndarray, node: np.ndarray,
                    heading: np.ndarray) -> np.ndarray:
    """Shortest-path actions for a batch, the rule of sim.dynamics.teacher_actions: turn toward
    the next hop by the smaller turn (left on a tie), forward when aligned, stop at the goal."""
    off = world.offset[episodes.run[idx]]
    hop = episodes.goal_next[idx, node - off]
    stop = (node == episodes.goal_node[idx]) | (hop < 0)
    hop = np.where(stop, node, hop + off)
    actions = actions_toward(world.ij[hop] - world.ij[node], heading)
    return np.where(stop, Action.STOP, actions).astype(np.int64)


def goal_distance(world: World, episodes: EpisodeSet, idx: np.ndarray, node: np.ndarray) -> np.ndarray:
    """Topological distance (metres) from global nodes to each episode's goal node."""
    return episodes.goal_dist[idx, node - world.offset[episodes.run[idx]]]


def splits_runs(bench: Benchmark, splits: list[str]) -> list[str]:
    """The runs that the given splits use, sorted."""
    return sorted({inst.run for s in splits for inst in bench.split(s)}, key=lambda r: (len(r), r))

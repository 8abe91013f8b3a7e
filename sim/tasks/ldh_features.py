"""What the Driver says and what each pose sees, in one shared vocabulary of sectors and labels.

Drivers localize by naming colours and objects and where they are ("a red wall to my left,
yellow ahead"). `mentions` turns a dialog's Driver turns into counts per (sector, label);
`pose_views` gives, for every (node, heading) of a graph, the fraction of the 13 rays of each
sector's view (front, left, behind, right: the camera turned 0, 90, 180, 270 degrees) that hit
each label near (within NEAR_M) or far. The language baseline and the learned localizer both
score poses from these two.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from sim.core.geometry import HEADINGS
from sim.core.labels import N_LABELS
from sim.core.maze import Maze
from sim.core.navgraph import NavGraph
from sim.core.observations import RayTable
from sim.language.sectors import LABEL_WORDS, NEAR_M, SECTOR_HEADING_OFFSET, SECTOR_WORDS, Sector

N_VIEW_SECTORS = 4
N_SECTORS = len(Sector)
MENTION_FEATURES = N_SECTORS * N_LABELS
VIEW_FEATURES = N_VIEW_SECTORS * N_LABELS * 2  # near and far

_WORD = re.compile(r"[a-z]+")
_CLAUSE = re.compile(r"[,.;!?]|\band\b|\bbut\b")


def mentions(dialog: Iterable[tuple[str, str]], roles: tuple[str, ...] = ("navigator",)) -> np.ndarray:
    """(N_SECTORS, N_LABELS) counts of labels the Driver names, each in the sector named in the
    same clause (the last one when a clause names several), else ANY."""
    out = np.zeros((N_SECTORS, N_LABELS), dtype=np.float32)
    for role, message in dialog:
        if role not in roles:
            continue
        for clause in _CLAUSE.split(message.lower().replace("ping-pong", "")):
            words = _WORD.findall(clause)
            labels = [LABEL_WORDS[w] for w in words if w in LABEL_WORDS]
            sectors = [SECTOR_WORDS[w] for w in words if w in SECTOR_WORDS]
            sector = sectors[-1] if sectors else Sector.ANY
            for label in labels:
                out[sector, label] += 1
    return out


def pose_views(rays: RayTable) -> np.ndarray:
    """(N, 8, N_VIEW_SECTORS, N_LABELS, 2) ray fractions per pose, sector, label, near/far."""
    n = rays.labels.shape[0]
    onehot = np.zeros((n, HEADINGS, rays.labels.shape[2], N_LABELS), dtype=np.float32)
    np.put_along_axis(onehot, rays.labels[..., None].astype(np.int64), 1.0, axis=-1)
    near = rays.depth[..., None] <= NEAR_M
    per_heading = np.stack([(onehot * near).mean(axis=2), (onehot * ~near).mean(axis=2)], axis=-1)
    headings = np.arange(HEADINGS)
    return np.stack([per_heading[:, (headings + k) % HEADINGS] for k in SECTOR_HEADING_OFFSET], axis=2)


def maze_views(maze: Maze, graph: NavGraph, cache_dir: str | Path | None = None) -> np.ndarray:
    return pose_views(RayTable.build(maze, graph, cache_dir=cache_dir))

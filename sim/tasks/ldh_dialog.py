"""The `dialog` LDH localizer and the per-turn curve (TD after each Driver turn, as DiaLoc reports).

`DialogLocalizer` runs the language-conditioned filter (`sim.language.localizer.Belief`) over an
instance's dialog on the maze's main component and takes the node minimising the expected TD,
as the other localizers do. Given a second reading of the Driver's turns (the trained Driver
reader), the belief weighs the mean of the two readings: a fact both read counts in full, one
only one of them reads half. `per_turn` scores
any localizer on the dialog cut after each Driver turn: turn 0 is before the Driver has said
anything. `calibration_records` gathers what `sim.language.calibration.fit` is fitted on.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import TypedDict

import numpy as np

from sim.core.geometry import HEADINGS, TURN_RAD
from sim.core.observations import RayTable
from sim.language.calibration import Record, evidence
from sim.language.localizer import HUMAN, Belief, Scene, Weights, fact_share
from sim.language.reader import Reader
from sim.language.understanding import belief_facts
from sim.tasks.benchmark import Benchmark
from sim.tasks.ldh import HUMANS_TD_M, LDHInstance
from sim.tasks.ldh_eval import ACC_RADII_M, Localizer, MazeContext, MazeContexts, score

DIALOG = "dialog"


class DialogLocalizer:
    """The filter over each maze's (node, heading) poses; scenes are built once per maze.
    `reader`: the Driver reader, a second reading of each Driver turn besides the rules' (None: the
    rules alone). Its own reading, not the agents' (`Understanding.facts`, which takes the rules'
    view where they have one): two readings that err apart weigh better than the rules twice
    (val_seen TD 0.607 against 0.659 m)."""

    def __init__(self, bench: Benchmark, weights: Weights = HUMAN, reader: Reader | None = None):
        self.bench = bench
        self.weights = weights
        self.reader = reader
        self._scenes: dict[str, Scene] = {}

    def scene(self, ctx: MazeContext) -> Scene:
        if ctx.run not in self._scenes:
            rays = RayTable.build(self.bench.maze(ctx.run), ctx.graph, cache_dir=self.bench.cache_dir)
            self._scenes[ctx.run] = Scene.from_rays(rays.labels, rays.depth, ctx.graph.nodes)
        return self._scenes[ctx.run]

    def __call__(self, inst: LDHInstance, ctx: MazeContext) -> np.ndarray:
        readings = 1 if self.reader is None else 2
        weights = replace(self.weights, sharpness=self.weights.sharpness / readings)
        belief = Belief(self.scene(ctx), ctx.main, weights)
        before: tuple[str, str] | None = None
        for role, message in inst.dialog:
            belief.message(role, message)
            if role == "navigator" and self.reader is not None:
                read = self.reader.read(message, before).meaning
                assert isinstance(read, frozenset)  # a Driver reader writes facts
                belief.observe(belief_facts(read))
            before = ("c" if role == "oracle" else "d", message)
        if not np.isfinite(belief.log).any() or np.ptp(belief.log[np.isfinite(belief.log)]) == 0:
            return ctx.one_hot(ctx.center)  # nothing said yet: the map's centre
        return ctx.one_hot(ctx.decide(belief.node_logits()))


def calibration_records(bench: Benchmark, instances: list[LDHInstance]) -> list[Record]:
    """Every fact the rules read in the Driver's turns that the calibration fits, with the share
    its true pose (the recorded start, turned as the Driver reported) bears out and every pose's."""
    shares = replace(HUMAN, calibration=None)  # the shares the calibration will score
    contexts, scenes = MazeContexts(bench), DialogLocalizer(bench, shares)
    out = []
    for inst in instances:
        if inst.heading is None:
            continue
        ctx = contexts[inst.run]
        scene = scenes.scene(ctx)
        true, start = ctx.graph.nearest_node(inst.x, inst.y), round(inst.heading / TURN_RAD)
        belief = Belief(scene, ctx.main, shares)
        for role, message in inst.dialog:
            for fact in belief.message(role, message):
                kind = evidence(fact)
                if kind is not None:
                    share = fact_share(fact, scene, shares)
                    heading = (start + belief.turned) % HEADINGS
                    out.append(Record(kind, float(share[true, heading]), share[ctx.main].ravel()))
    return out


def driver_cuts(inst: LDHInstance) -> list[int]:
    """Dialog lengths to score: before any Driver turn, then after each one."""
    first = next((k for k, (role, _) in enumerate(inst.dialog) if role == "navigator"), len(inst.dialog))
    return [first] + [k + 1 for k, (role, _) in enumerate(inst.dialog) if role == "navigator"]


class TurnCurves(TypedDict):
    turns: list[int]  # 0, 1, ...
    n: list[int]  # instances with at least that many Driver turns
    agents: dict[str, dict[str, list[float]]]  # NAME -> td_mean, td_median, acc_0.25, acc_0.5: one per turn


def per_turn(
    bench: Benchmark,
    instances: list[LDHInstance],
    agents: dict[str, Localizer],
    contexts: MazeContexts | None = None,
) -> TurnCurves:
    """After turn t, each instance's TD with its dialog cut after its t-th Driver turn, or whole
    when it has fewer (the estimate stays where its dialog left it)."""
    contexts = contexts or MazeContexts(bench)
    cuts = {inst.inst_idx: driver_cuts(inst) for inst in instances}
    turns = max(len(c) for c in cuts.values())
    tds: dict[str, np.ndarray] = {name: np.zeros((len(instances), turns)) for name in agents}
    for i, inst in enumerate(instances):
        ctx = contexts[inst.run]
        inst_cuts = cuts[inst.inst_idx]
        for name, localizer in agents.items():
            row = [score(ctx, localizer(replace(inst, dialog=inst.dialog[:cut]), ctx), inst)[0] for cut in inst_cuts]
            tds[name][i] = row + [row[-1]] * (turns - len(row))
    out: TurnCurves = {
        "turns": list(range(turns)),
        "n": [sum(len(c) > t for c in cuts.values()) for t in range(turns)],
        "agents": {},
    }
    for name, td in tds.items():
        curve = {"td_mean": td.mean(axis=0).tolist(), "td_median": np.median(td, axis=0).tolist()}
        for r in ACC_RADII_M[:2]:
            curve[f"acc_{r}"] = (td <= r).mean(axis=0).tolist()
        out["agents"][name] = curve
    return out


def plot_curve(curve: TurnCurves, path: str | Path, title: str) -> None:
    """Mean TD after each Driver turn, one line per agent (and the humans' final TD, dashed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 3.8))
    for name, c in curve["agents"].items():
        ax.plot(curve["turns"], c["td_mean"], marker="o", ms=3, label=name)
    ax.axhline(HUMANS_TD_M, color="grey", ls="--", lw=1, label=f"humans (paper) {HUMANS_TD_M} m")
    ax.set_xlabel("Driver turns read")
    ax.set_ylabel("mean TD (m)")
    ax.set_title(title)
    ax.set_ylim(bottom=0)
    ax2 = ax.twinx()
    ax2.bar(curve["turns"], curve["n"], color="grey", alpha=0.15, width=0.6)
    ax2.set_ylabel("dialogs still going", color="grey")
    ax.set_zorder(ax2.get_zorder() + 1)
    ax.patch.set_visible(False)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    plt.close(fig)

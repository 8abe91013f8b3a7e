"""A learned LDH localizer: the Driver's words matched against what every pose sees.

The dialog becomes counts of the labels the Driver names per direction (`sim.tasks.ldh_features.
mentions`, 5 x 10); each (node, heading) becomes the share of its four views' rays hitting
each label near and far (4 x 10 x 2). A bilinear map scores every pose from the two, on top of
the colour baseline's log-likelihood (a learned weight; ingredient `prior`). Training minimises
the cross-entropy of the node belief against a target that decays with TD from the truth, so
near misses cost little, as the metric. 118 training dialogs are few: the model is small
(a 50 x 80 bilinear map), dropout on the mentions regularises it (ingredient `dropout`), and
synthetic Driver descriptions of random poses of the training mazes, written from the
simulator's rays, can be mixed in (ingredient `synthetic`; off by default, since on val_seen
they hurt: their phrasing and what they pick to name differ from real Drivers').
The prediction is the node minimising the expected TD under the belief.
"""

from __future__ import annotations

import json
import math
import random
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from sim.core.labels import OBJECT_LABELS, WALL_LABELS, Label
from sim.tasks.benchmark import Benchmark
from sim.tasks.ldh import LDHInstance, Variant, load_split
from sim.tasks.ldh_eval import MazeContext, MazeContexts, colour_features, evaluate, summarize
from sim.tasks.ldh_features import MENTION_FEATURES, VIEW_FEATURES, mentions

FORMAT = "robotslang-ldh-v1"
TARGET_SCALE_M = 0.15  # the training target's decay with TD from the truth


@dataclass
class LDHConfig:
    seed: int = 0
    epochs: int = 30
    synthetic: int = 0  # synthetic descriptions per epoch; 0 = real dialogs only (best on val_seen)
    dropout: float = 0.5
    prior: bool = True
    lr: float = 3e-3
    variant: str = Variant.PREFIX.value


class Localizer(nn.Module):
    def __init__(self, dropout: float, prior: bool):
        super().__init__()
        self.dropout = nn.Dropout(dropout)
        self.bilinear = nn.Parameter(torch.zeros(MENTION_FEATURES, VIEW_FEATURES))
        self.view_bias = nn.Parameter(torch.zeros(VIEW_FEATURES))
        self.prior_weight = nn.Parameter(torch.tensor(1.0 if prior else 0.0), requires_grad=prior)

    def forward(self, counts: torch.Tensor, pose: PoseTensors) -> torch.Tensor:
        """counts (5, 10) -> pose logits (P,) over the maze's (node, heading) poses."""
        flat = counts.flatten()
        text = self.dropout(torch.log1p(flat))
        return pose.views @ (text @ self.bilinear + self.view_bias) + self.prior_weight * (pose.prior @ flat)


@dataclass(frozen=True)
class PoseTensors:
    """A maze's poses as the model reads them, built once per maze."""

    views: torch.Tensor  # (P, VIEW_FEATURES)
    prior: torch.Tensor  # (P, MENTION_FEATURES): the colour baseline's per-mention log-likelihoods
    main: torch.Tensor  # (N,) bool

    @classmethod
    def of(cls, ctx: MazeContext) -> PoseTensors:
        views = ctx.required_views
        n, headings = views.shape[:2]
        return cls(
            views=torch.from_numpy(views.reshape(n * headings, -1)),
            prior=torch.from_numpy(colour_features(views).reshape(n * headings, -1)),
            main=torch.from_numpy(ctx.main),
        )


class TrainedLocalizer:
    """A trained model as a `sim.tasks.ldh_eval.Localizer`."""

    def __init__(self, model: Localizer):
        self.model = model.eval()
        self._poses: dict[str, PoseTensors] = {}

    def logits(self, counts: np.ndarray, ctx: MazeContext) -> np.ndarray:
        if ctx.run not in self._poses:
            self._poses[ctx.run] = PoseTensors.of(ctx)
        with torch.no_grad():
            out = self.model(torch.from_numpy(counts), self._poses[ctx.run])
        return out.numpy().reshape(ctx.graph.n, -1)

    def __call__(self, inst: LDHInstance, ctx: MazeContext) -> np.ndarray:
        return ctx.one_hot(ctx.decide(self.logits(mentions(inst.dialog), ctx)))


def load_localizer(path: str | Path) -> TrainedLocalizer:
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such checkpoint")
    try:
        data = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # torch raises pickle, zip and runtime errors alike for a bad file
        raise ValueError(f"{path}: not a checkpoint ({type(e).__name__})") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ValueError(f"{path}: not an LDH checkpoint (expected format {FORMAT})")
    cfg = data["config"]
    model = Localizer(cfg["dropout"], cfg["prior"])
    try:
        model.load_state_dict(data["state"])
    except (RuntimeError, KeyError) as e:
        raise ValueError(f"{path}: weights do not fit the LDH model ({e})") from None
    return TrainedLocalizer(model)


_DIRECTION_TEXT = {
    0: ("in front of me", "ahead"),
    1: ("to my left", "on my left"),
    2: ("behind me",),
    3: ("to my right", "on my right"),
}


def synthetic_description(ctx: MazeContext, node: int, heading: int, rng: random.Random) -> tuple:
    """A Driver's description of a pose from its rays: for some directions, the label most of
    that view's rays hit (near first), as a Driver would name it."""
    views = ctx.required_views[node, heading]  # (4, labels, 2)
    clauses = []
    for sector in rng.sample(range(4), k=rng.randint(1, 3)):
        share = views[sector, :, 0] + 0.3 * views[sector, :, 1]
        label = Label(int(max((*WALL_LABELS, *OBJECT_LABELS), key=lambda lab: share[lab])))
        if share[label] == 0:
            continue
        what = f"the {label.word}" if label in OBJECT_LABELS else f"a {label.word} wall"
        where = "" if rng.random() < 0.15 else " " + rng.choice(_DIRECTION_TEXT[sector])
        clauses.append(f"{what}{where}")
    return (("navigator", "I see " + ", ".join(clauses) if clauses else "hello"),)


def _target(ctx: MazeContext, x: float, y: float) -> np.ndarray:
    true = ctx.graph.nearest_node(x, y)
    q = np.where(ctx.main, np.exp(-ctx.graph.dist[:, true] / TARGET_SCALE_M), 0.0)
    return (q / q.sum()).astype(np.float32)


def _loss(
    model: Localizer, ctx: MazeContext, pose: PoseTensors, counts: np.ndarray, target: np.ndarray
) -> torch.Tensor:
    logits = model(torch.from_numpy(counts), pose).reshape(ctx.graph.n, -1)
    logits = logits.masked_fill(~pose.main[:, None], -1e9)
    node_logp = torch.logsumexp(logits, dim=1) - torch.logsumexp(logits.flatten(), dim=0)
    return -(torch.from_numpy(target) * node_logp).sum()


def train(
    bench: Benchmark, cfg: LDHConfig, out: str | Path, contexts: MazeContexts | None = None, progress: bool = True
) -> dict:
    """Train, validating on val_seen after each epoch; DIR/best.pt is the best val_seen TD."""
    from tqdm import tqdm

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    random.seed(cfg.seed)
    np.random.seed(cfg.seed)
    torch.manual_seed(cfg.seed)
    torch.set_num_threads(1)  # small matrices: threads only contend on the shared cores
    rng = random.Random(cfg.seed)
    contexts = contexts or MazeContexts(bench)
    variant = Variant(cfg.variant)
    train_set = load_split(bench, "train", variant)
    val_set = load_split(bench, "val_seen", variant)
    if not train_set or not val_set:
        raise ValueError("train and val_seen need LDH instances")
    real = [(inst.run, mentions(inst.dialog), inst.x, inst.y) for inst in train_set]
    runs = sorted({inst.run for inst in train_set})
    poses = {run: PoseTensors.of(contexts[run]) for run in runs}
    model = Localizer(cfg.dropout, cfg.prior)
    opt = torch.optim.Adam(model.parameters(), lr=cfg.lr, weight_decay=1e-4)
    history, best = [], {"epoch": None, "val_td": math.inf}
    best_td = math.inf
    start = time.time()
    bar = tqdm(range(cfg.epochs), desc=f"train ldh seed {cfg.seed}", disable=not progress)
    for epoch in bar:
        examples = list(real)
        for _ in range(cfg.synthetic):
            ctx = contexts[rng.choice(runs)]
            node = int(rng.choice(np.flatnonzero(ctx.main)))
            heading = rng.randrange(ctx.required_views.shape[1])
            x, y = ctx.graph.nodes[node]
            examples.append((ctx.run, mentions(synthetic_description(ctx, node, heading, rng)), x, y))
        rng.shuffle(examples)
        model.train()
        total = 0.0
        for run, counts, x, y in examples:
            ctx = contexts[run]
            loss = _loss(model, ctx, poses[run], counts, _target(ctx, x, y))
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += loss.item()
        localizer = TrainedLocalizer(model)
        val = summarize(
            "val_seen",
            variant.value,
            len(val_set),
            evaluate(bench, "val_seen", val_set, {"learned": localizer}, contexts=contexts),
        )
        val_td = val["agents"]["learned"]["td_mean"]
        history.append({"epoch": epoch, "loss": total / len(examples), "val_td": val_td})
        bar.set_postfix(loss=f"{total / len(examples):.3f}", val_td=f"{val_td:.3f}")
        if val_td < best_td:
            best, best_td = {"epoch": epoch, "val_td": val_td}, val_td
            save(model, cfg, out / "best.pt")
        model.train()
    result = {"config": asdict(cfg), "best": best, "history": history, "seconds": time.time() - start}
    (out / "history.json").write_text(json.dumps(result, indent=1))
    return result


def save(model: Localizer, cfg: LDHConfig, path: Path) -> None:
    torch.save({"format": FORMAT, "config": asdict(cfg), "state": model.state_dict()}, path)

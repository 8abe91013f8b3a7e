"""Training the NDH seq2seq Driver: teacher or student forcing, validation TD, checkpoints.

`train(...)` writes `OUT/last.pt` at every validation (and at the end) and `OUT/best.pt` for
the best validation TD so far; started again on the same OUT it resumes from `last.pt`.
Every iteration draws its batch and its sampling noise from (seed, iteration), so a resumed
run repeats exactly what an uninterrupted one would have done.
"""

from __future__ import annotations

import copy
import json
import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from models.agent import AgentConfig, Seq2SeqAgent
from models.data import EpisodeSet, World, goal_distance
from models.rollout import BLINDS, MAX_ACTIONS, run_episodes
from models.tokenizer import Tokenizer
from sim.tasks.benchmark import Benchmark, NDHInstance, Split

FEEDBACK_LR = {"teacher": 1e-4, "student": 1e-3}


@dataclass(frozen=True)
class ModelSetup:
    """A named learned Driver: its agent's options and how it is trained."""

    agent: dict  # AgentConfig options
    weight_average: float = 0.0  # decay of the running average of the weights that is validated
    # and saved for evaluation (0: the weights as trained)
    guided_share: float = 0.0  # share of each student-forced batch that follows the teacher, so
    # the stop (the policy's and the stop head's) is learned where the goal is reached


# Named model setups: the paper's model; the one that beats it (target flags, the actor-critic
# loss on the distance covered, averaged weights, a stop head that ends its episodes, half of
# each batch guided to the goal so the stop is learned, and at test time a cost on re-entering
# poses); and attention with a progress monitor, tried and kept as an option
# (docs/learned_driver.md).
MODELS = {
    "baseline": ModelSetup({}),
    "improved": ModelSetup(
        {"target_rays": True, "critic": True, "stop_head": True, "revisit_penalty": 1.0},
        weight_average=0.95,
        guided_share=0.5,
    ),
    "attention": ModelSetup({"attention": True, "progress_monitor": True, "target_rays": True}),
}


@dataclass
class TrainConfig:
    feedback: str = "student"
    blind: str = "none"
    seed: int = 0
    iters: int = 2000
    batch: int = 100
    lr: float | None = None  # None: the paper's rate for the feedback
    eval_every: int = 200
    max_actions: int = MAX_ACTIONS
    model: str = "baseline"
    train_splits: list[str] = field(default_factory=lambda: ["train"])
    eval_split: str | None = "val_seen"
    min_count: int = 1
    glove: str | None = None

    def __post_init__(self):
        if self.feedback not in FEEDBACK_LR:
            raise ValueError(f"unknown feedback {self.feedback!r}; expected teacher or student")
        if self.blind not in BLINDS:
            raise ValueError(f"unknown ablation {self.blind!r}; expected one of {', '.join(BLINDS)}")
        if self.model not in MODELS:
            raise ValueError(f"unknown model {self.model!r}; expected one of {', '.join(MODELS)}")
        for s in self.train_splits + ([self.eval_split] if self.eval_split else []):
            if s not in tuple(Split):
                raise ValueError(f"unknown split {s!r}; expected one of {', '.join(Split)}")
        if self.iters < 1 or self.batch < 1 or self.eval_every < 1:
            raise ValueError("iters, batch and eval_every must be positive")

    @property
    def learning_rate(self) -> float:
        return self.lr if self.lr is not None else FEEDBACK_LR[self.feedback]


def build_world(bench: Benchmark, cache_dir=None) -> World:
    """One world for every split, so each maze is compiled (and cached) once."""
    runs = sorted({inst.run for split in Split for inst in bench.split(split)}, key=lambda r: (len(r), r))
    return World.build(bench, runs, cache_dir=cache_dir)


def load_glove(path: str | Path, tokenizer: Tokenizer) -> tuple[torch.Tensor, int]:
    """Rows for the vocabulary from a GloVe text file; words it lacks keep a random row."""
    vectors: dict[str, np.ndarray] = {}
    with open(path, encoding="utf8") as f:
        for line_no, line in enumerate(f, 1):
            word, *values = line.rstrip().split(" ")
            if word in tokenizer.index:
                try:
                    vectors[word] = np.asarray(values, dtype=np.float32)
                except ValueError:
                    raise ValueError(f"{path}:{line_no}: not a GloVe line (word then numbers)") from None
    if not vectors:
        raise ValueError(f"{path}: no vectors for any vocabulary word; is this a GloVe text file?")
    dim = len(next(iter(vectors.values())))
    table = torch.randn(len(tokenizer), dim) * 0.1
    for word, vec in vectors.items():
        if len(vec) != dim:
            raise ValueError(f"{path}: vector for {word!r} has {len(vec)} values, expected {dim}")
        table[tokenizer.index[word]] = torch.from_numpy(vec)
    table[0] = 0.0
    return table, dim


def make_agent(cfg: TrainConfig, tokenizer: Tokenizer, obs_features: int) -> Seq2SeqAgent:
    glove, embed = load_glove(cfg.glove, tokenizer) if cfg.glove else (None, 128)
    agent = Seq2SeqAgent(
        AgentConfig(vocab_size=len(tokenizer), obs_features=obs_features, embed=embed, **MODELS[cfg.model].agent)
    )
    if glove is not None:
        agent.embedding.weight.data.copy_(glove)
    return agent


@torch.no_grad()
def validation_td(
    agent: Seq2SeqAgent, world: World, episodes: EpisodeSet, blind: str, max_actions: int = MAX_ACTIONS
) -> float:
    """Mean topological distance to the goal where the greedy agent stops."""
    agent.eval()
    idx = np.arange(len(episodes))
    roll = run_episodes(agent, world, episodes, idx, "argmax", blind, max_actions)
    agent.train()
    td = goal_distance(world, episodes, idx, roll.final_node)
    return float(td[np.isfinite(td)].mean())


def save_checkpoint(path: Path, agent, averaged, optimizer, tokenizer, cfg, iteration, history, best) -> None:
    """`state_dict` is what training resumes from; `eval_state_dict`, where the variant averages
    its weights, is what a Driver loaded from the checkpoint plays with."""
    tmp = path.with_suffix(".tmp")
    torch.save(
        {
            "agent_config": asdict(agent.config),
            "state_dict": agent.state_dict(),
            "eval_state_dict": averaged.state_dict() if averaged is not None else None,
            "optimizer": optimizer.state_dict(),
            "tokenizer": tokenizer.to_json(),
            "train_config": asdict(cfg),
            "iteration": iteration,
            "history": history,
            "best": best,
        },
        tmp,
    )
    tmp.replace(path)  # never a half-written checkpoint


@torch.no_grad()
def update_average(averaged: Seq2SeqAgent, agent: Seq2SeqAgent, decay: float) -> None:
    for avg, new in zip(averaged.parameters(), agent.parameters()):
        avg.mul_(decay).add_(new, alpha=1.0 - decay)


def load_agent(path: str | Path) -> tuple[Seq2SeqAgent, Tokenizer, dict]:
    """The agent of a checkpoint (in eval mode), its tokenizer, and the whole checkpoint dict."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such checkpoint")
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=False)
        agent = Seq2SeqAgent(AgentConfig(**ckpt["agent_config"]))
        agent.load_state_dict(ckpt.get("eval_state_dict") or ckpt["state_dict"])
    except (KeyError, RuntimeError, EOFError, OSError) as exc:
        raise ValueError(f"{path}: not a seq2seq Driver checkpoint ({exc})") from None
    agent.eval()
    return agent, Tokenizer.from_json(ckpt["tokenizer"]), ckpt


def train(
    bench: Benchmark,
    cfg: TrainConfig,
    out: str | Path,
    world: World | None = None,
    progress: bool = True,
    threads: int | None = None,
    train_instances: list[NDHInstance] | None = None,
    eval_instances: list[NDHInstance] | None = None,
) -> dict:
    """Train (or resume) into `out`; returns {"history": [...], "best": {...}, "seconds": s}.

    `train_instances` / `eval_instances` replace the configured splits (small runs, tests).
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if threads:
        torch.set_num_threads(threads)
    if world is None and train_instances is None and eval_instances is None:
        world = build_world(bench, bench.cache_dir)
    if train_instances is None:
        train_instances = [inst for s in cfg.train_splits for inst in bench.split(s)]
    if world is None:
        used = train_instances + (eval_instances or (bench.split(cfg.eval_split) if cfg.eval_split else []))
        world = World.build(bench, sorted({inst.run for inst in used}), cache_dir=bench.cache_dir)
    tokenizer = Tokenizer.from_dialogs(((i.dialog, i.target) for i in train_instances), cfg.min_count)
    train_set = EpisodeSet.build(bench, world, "+".join(cfg.train_splits), tokenizer, instances=train_instances)
    val_set = (
        EpisodeSet.build(bench, world, cfg.eval_split, tokenizer, instances=eval_instances) if cfg.eval_split else None
    )

    torch.manual_seed(cfg.seed)
    agent = make_agent(cfg, tokenizer, world.obs_features)
    optimizer = torch.optim.Adam(agent.parameters(), lr=cfg.learning_rate)
    decay = MODELS[cfg.model].weight_average
    averaged = copy.deepcopy(agent) if decay else None
    start, history, best = 0, [], {"iteration": None, "val_td": math.inf}
    last = out / "last.pt"
    if last.exists():
        _, _, ckpt = load_agent(last)
        if ckpt["train_config"] != {**asdict(cfg), "iters": ckpt["train_config"]["iters"]}:
            raise ValueError(
                f"{last}: was trained with a different configuration ({ckpt['train_config']}); use another --out"
            )
        agent.load_state_dict(ckpt["state_dict"])
        if averaged is not None:
            averaged.load_state_dict(ckpt["eval_state_dict"])
        optimizer.load_state_dict(ckpt["optimizer"])
        tokenizer = Tokenizer.from_json(ckpt["tokenizer"])
        start, history, best = ckpt["iteration"], ckpt["history"], ckpt["best"]
    (out / "config.json").write_text(json.dumps(asdict(cfg), indent=2))

    agent.train()
    began = time.perf_counter()
    bar = tqdm(
        range(start, cfg.iters),
        initial=start,
        total=cfg.iters,
        disable=not progress,
        desc=f"{cfg.model} {cfg.feedback}/{cfg.blind} seed {cfg.seed}",
        unit="it",
    )
    window: list[float] = []
    for it in bar:
        rng = np.random.default_rng([cfg.seed, it])
        torch.manual_seed(cfg.seed * 1_000_003 + it)
        gen = torch.Generator().manual_seed(cfg.seed * 1_000_003 + it)
        idx = rng.choice(len(train_set), size=min(cfg.batch, len(train_set)), replace=False)
        roll = run_episodes(
            agent,
            world,
            train_set,
            idx,
            cfg.feedback,
            cfg.blind,
            cfg.max_actions,
            generator=gen,
            train=True,
            guided_share=MODELS[cfg.model].guided_share,
        )
        optimizer.zero_grad()
        assert roll.loss is not None  # train=True: the rollout computes its loss
        roll.loss.backward()
        optimizer.step()
        if averaged is not None:
            update_average(averaged, agent, decay)
        window.append(roll.loss.item())  # losses since the last validation
        done = it + 1
        postfix = {"loss": f"{np.mean(window):.3f}"}  # before `window` restarts below
        if done % cfg.eval_every == 0 or done == cfg.iters:
            entry = {"iteration": done, "loss": float(np.mean(window)), "seconds": time.perf_counter() - began}
            if val_set is not None:
                entry["val_td"] = validation_td(
                    averaged if averaged is not None else agent, world, val_set, cfg.blind, cfg.max_actions
                )
                if entry["val_td"] < best["val_td"]:
                    best = {"iteration": done, "val_td": entry["val_td"]}
                    save_checkpoint(
                        out / "best.pt", agent, averaged, optimizer, tokenizer, cfg, done, history + [entry], best
                    )
            history.append(entry)
            window = []
            save_checkpoint(last, agent, averaged, optimizer, tokenizer, cfg, done, history, best)
            (out / "history.json").write_text(json.dumps(history, indent=1))
        if best["iteration"] is not None:
            postfix["val_td"] = f"{history[-1].get('val_td', math.nan):.2f}"
            postfix["best"] = f"{best['val_td']:.2f}@{best['iteration']}"
        bar.set_postfix(postfix)
    return {"history": history, "best": best, "seconds": time.perf_counter() - began}

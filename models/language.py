"""Training the dialog reader (`sim.language.reader`): `robotslang train language`.

Two readers, one per seat's words: Commander turns into programs, Driver turns into fact sets.
Their examples are the train split's turns only, labelled two ways:
- by hand (`models/language_data/*.jsonl`: the same guide as the gold set, docs/language_gold.md;
  each turn by its name and text hash, the text read from the benchmark);
- by the rules, on the project's own agents' words: offline self-play trials on train mazes
  (the dialog Commander with the dialog Driver, the oracle Commander in the scripted phrasing with
  the dialog Driver), whose messages the rules were written to read, and the platform's own
  vocabulary of questions and instructions (`vocabulary_examples`). These keep the readers fluent
  in what the platform's agents say to each other.
Nothing here reads the val_seen or test dialogs, nor the gold set.

The network is the one `sim.language.reader` runs in numpy; the weights are exported there.
"""

from __future__ import annotations

import json
import random
import time
from collections import Counter
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn
from tqdm import tqdm

from models.language_paraphrase import paraphrase_examples
from sim.agents.dialog_commander import LOOK_AROUND, DialogCommander
from sim.agents.dialog_driver import DialogDriver
from sim.agents.oracle_commander import OracleCommander
from sim.core.labels import OBJECT_LABELS, WALL_LABELS
from sim.language import instructions as ins
from sim.language import lexicon
from sim.language.meaning import Clause, FactForm, facts_of, program_of
from sim.language.phrases import PhraseKind, Phrases, Phrasing
from sim.language.reader import (
    BOS,
    EOS,
    MAX_NUMBERS,
    PAD,
    SEP,
    UNK,
    Role,
    encode_meaning,
    output_vocabulary,
    source_tokens,
)
from sim.language.understanding import Understanding
from sim.language.vocab import OBJECT_WORDS, wall_name
from sim.tasks.benchmark import Benchmark, Split, text_hash
from sim.trial.agent import Agent

LABELS_DIR = Path(__file__).with_name("language_data")
# The benchmark's speaker names and self-play's (`Speaker` values), as the reader's context tags.
SPEAKER = {"oracle": "c", "navigator": "d", "commander": "c", "driver": "d"}
ROLE_OF = {"oracle": Role.COMMANDER, "navigator": Role.DRIVER}
FIXED_SOURCE = [PAD, UNK, SEP, "<c>", "<d>", "<n>", "<num>", *(f"<num{k}>" for k in range(MAX_NUMBERS))]


@dataclass(frozen=True)
class Example:
    source: tuple[str, ...]
    target: tuple[str, ...]


@dataclass(frozen=True)
class Config:
    seed: int = 0
    epochs: int = 40
    batch: int = 32
    lr: float = 3e-3
    embed: int = 64
    hidden: int = 128  # each direction of the encoder
    decoder: int = 192
    dropout: float = 0.25
    word_dropout: float = 0.08  # source words replaced by <unk> while training
    selfplay_trials: int = 40  # train mazes played for the rules-labelled examples
    paraphrases: int = 2500  # Commander turns by paraphrase, labelled as built


def _example(role: Role, text: str, before: tuple[str, str] | None, meaning: Any) -> Example:
    source, numbers = source_tokens(text, before)
    return Example(tuple(source), tuple(encode_meaning(role, meaning, numbers)))


def _before(dialog: Sequence[tuple[str, str]], index: int) -> tuple[str, str] | None:
    if index == 0:
        return None
    role, text = dialog[index - 1]
    return SPEAKER[role], text


def hand_examples(bench: Benchmark, role: Role, labels_dir: Path = LABELS_DIR) -> list[Example]:
    """The hand-labelled train turns of `role`; a turn whose text changed stops training."""
    dialogs = bench.dialogs(Split.TRAIN)
    out: list[Example] = []
    key = "program" if role == Role.COMMANDER else "facts"
    with (labels_dir / f"{role.value}.jsonl").open() as f:
        for line in f:
            record = json.loads(line)
            split, run, index = record["id"].split("/")
            if split != Split.TRAIN:
                raise ValueError(f"{record['id']}: the reader is trained on the train split only")
            dialog = dialogs[run]
            speaker, text = dialog[int(index)]
            if text_hash(text) != record["text_sha256"] or ROLE_OF[speaker] != role:
                raise ValueError(f"{record['id']}: not the turn that was labelled (benchmark changed?)")
            meaning: Any = (
                tuple(Clause.from_json(c) for c in record[key])
                if role == Role.COMMANDER
                else frozenset(FactForm.from_json(f) for f in record[key])
            )
            out.append(_example(role, text, _before(dialog, int(index)), meaning))
    return out


# What the dialog Driver says before a Commander speaks: the context a Commander turn is read in.
DRIVER_REPORTS = [
    None,
    "ok, turned left, red wall close ahead. what next?",
    "ok, went 3 steps, white wall far ahead, blue wall on my left. where to now?",
    "i hit a wall, which way now?",
    "i am in a corner, green wall close ahead, close white wall on my left",
    "ok, not here then. where should i go?",
]


def vocabulary_examples(seed: int, n: int = 2500) -> list[Example]:
    """Commander turns in the platform's own words, composed as its Commanders compose them (the
    scripted templates joined as `sim.agents.route` joins them, the dialog Commander's questions),
    with the questions and history a person's vocabulary adds; labelled by the rules written for them."""
    rng = random.Random(seed)
    said = Phrases(Phrasing.SCRIPTED, seed)
    walls = [wall_name(label) for label in WALL_LABELS] + [wall_name(label) for label in OBJECT_LABELS]
    things = list(OBJECT_WORDS.values())
    sides = ["on your left", "on your right", "behind you", "ahead of you"]
    ordinals = ["first", "second", "third"]

    def turn() -> str:
        return said.turn(rng.choice([1, 2, 3, 4, -1, -2, -3])) or "turn around"

    def route() -> str:
        words = [turn() for _ in range(rng.choice([0, 0, 1]))]
        last = rng.choice(
            [
                lambda: said.say(PhraseKind.FORWARD, n=rng.randint(1, 20)),
                lambda: said.say(PhraseKind.FORWARD_THEN_TURN, n=rng.randint(1, 20), turn=turn()),
                lambda: said.say(PhraseKind.TURN_AT_WALL, turn=turn(), wall=rng.choice(walls)),
                lambda: said.say(PhraseKind.UNTIL_TARGET, thing=rng.choice(things)),
            ]
        )()
        return ", then ".join([*words, last])

    forms = [
        route,
        route,
        route,
        lambda: f"{said.say(PhraseKind.ANNOUNCE, thing=rng.choice(things))}. {route()}",
        lambda: said.say(PhraseKind.THERE, thing=rng.choice(things)),
        lambda: said.say(PhraseKind.ASK_VIEW),
        lambda: f"stop there. {LOOK_AROUND}?",
        lambda: f"is there a {rng.choice(walls)} {rng.choice(sides)}?",
        lambda: f"what is {rng.choice(sides)}?",
        lambda: f"go back to where you {rng.choice(['started', 'began'])}",
        lambda: f"go back to where you turned {rng.choice(['left', 'right'])} {rng.choice(ordinals)}",
        lambda: f"take the {rng.choice(ordinals)} {rng.choice(['left', 'right'])}",
        lambda: rng.choice(["stop", "wait", "hold on", "you're there, that's it", "stop there and take a picture"]),
    ]
    out = []
    for _ in range(n):
        text = rng.choice(forms)()
        report = rng.choice(DRIVER_REPORTS)
        out.append(
            _example(Role.COMMANDER, text, None if report is None else ("d", report), program_of(ins.parse(text)))
        )
    return out


def paraphrased_examples(seed: int, n: int) -> list[Example]:
    """Commander turns by paraphrase (`models.language_paraphrase`), labelled as they were built."""
    rng = random.Random(seed)
    return [
        _example(
            Role.COMMANDER, text, None if (report := rng.choice(DRIVER_REPORTS)) is None else ("d", report), program
        )
        for text, program in paraphrase_examples(seed, n)
    ]


def selfplay_examples(bench: Benchmark, trials: int, seed: int) -> dict[Role, list[Example]]:
    """The agents' own words on train mazes, labelled by the rules written for them (deduplicated)."""
    from sim.agents import selfplay

    specs = selfplay.benchmark_trials(bench, Split.TRAIN)
    random.Random(seed).shuffle(specs)
    seen: set[tuple[str, tuple[str, str] | None]] = set()
    out: dict[Role, list[Example]] = {Role.COMMANDER: [], Role.DRIVER: []}
    rules = Understanding.by_rules()  # the agents read by the rules: the data does not depend on a reader
    for k, spec in enumerate(tqdm(specs[:trials], desc="self-play for the agents' words", unit="trial")):
        maze, graph, rays = selfplay.world(str(bench.root), spec.maze)
        commander: Agent = (
            DialogCommander(maze, spec.seed, bench.cache_dir, understanding=rules)
            if k % 2 == 0
            else OracleCommander(graph, rays, list(spec.targets), seed=spec.seed)
        )
        result = selfplay.play(commander, DialogDriver(spec.seed, understanding=rules), graph, rays, spec)
        dialog = result.dialog
        for index, (speaker, text) in enumerate(dialog):
            before = _before(dialog, index)
            if (text, before) in seen:
                continue
            seen.add((text, before))
            if SPEAKER[speaker] == "c":
                out[Role.COMMANDER].append(_example(Role.COMMANDER, text, before, program_of(ins.parse(text))))
            else:
                out[Role.DRIVER].append(
                    _example(
                        Role.DRIVER,
                        text,
                        before,
                        facts_of(text, lexicon.asked((SPEAKER[r] == "c", t) for r, t in dialog[:index])),
                    )
                )
    return out


class Seq2Seq(nn.Module):
    """The reader's network; `sim.language.reader.Reader` runs the same in numpy."""

    def __init__(self, n_source: int, n_target: int, cfg: Config) -> None:
        super().__init__()
        self.embed = nn.Embedding(n_source, cfg.embed, padding_idx=0)
        self.encoder = nn.GRU(cfg.embed, cfg.hidden, batch_first=True, bidirectional=True)
        self.bridge = nn.Linear(2 * cfg.hidden, cfg.decoder)
        self.out_embed = nn.Embedding(n_target, cfg.embed)
        self.decoder = nn.GRUCell(cfg.embed + 2 * cfg.hidden, cfg.decoder)
        self.attn = nn.Linear(2 * cfg.hidden, cfg.decoder, bias=False)
        self.out = nn.Linear(cfg.decoder + 2 * cfg.hidden, n_target)
        self.drop = nn.Dropout(cfg.dropout)

    def forward(self, source: torch.Tensor, lengths: torch.Tensor, target_in: torch.Tensor) -> torch.Tensor:
        x = self.drop(self.embed(source))
        packed = nn.utils.rnn.pack_padded_sequence(x, lengths, batch_first=True, enforce_sorted=False)
        states_packed, h_n = self.encoder(packed)
        states, _ = nn.utils.rnn.pad_packed_sequence(states_packed, batch_first=True, total_length=source.shape[1])
        h = torch.tanh(self.bridge(torch.cat([h_n[0], h_n[1]], dim=1)))
        keys = self.attn(states)  # (B, T, D)
        pad = source == 0
        context = torch.zeros(source.shape[0], states.shape[2])
        logits = []
        for t in range(target_in.shape[1]):
            step = torch.cat([self.drop(self.out_embed(target_in[:, t])), context], dim=1)
            h = self.decoder(step, h)
            scores = torch.einsum("btd,bd->bt", keys, h).masked_fill(pad, -1e9)
            attn = torch.softmax(scores, dim=1)
            context = torch.einsum("bt,btd->bd", attn, states)
            logits.append(self.out(self.drop(torch.cat([h, context], dim=1))))
        return torch.stack(logits, dim=1)


def _batches(
    examples: Sequence[Example], src: dict[str, int], tgt: dict[str, int], cfg: Config, rng: random.Random
) -> Iterator[tuple[torch.Tensor, ...]]:
    # Batches of examples of about one length (a Driver's fact list runs to 40 tokens, most to a
    # few): the decoder's steps are the cost, and padding a short reading to a long one wastes them.
    order = list(range(len(examples)))
    rng.shuffle(order)
    order.sort(key=lambda i: (len(examples[i].target), len(examples[i].source)))
    batches = [order[start : start + cfg.batch] for start in range(0, len(order), cfg.batch)]
    rng.shuffle(batches)
    for batch in batches:
        chunk = [examples[i] for i in batch]
        width = max(len(e.source) for e in chunk)
        depth = max(len(e.target) for e in chunk) + 1
        source = torch.zeros(len(chunk), width, dtype=torch.long)
        target_in = torch.zeros(len(chunk), depth, dtype=torch.long)
        target_out = torch.zeros(len(chunk), depth, dtype=torch.long)
        for b, e in enumerate(chunk):
            ids = [src.get(t, src[UNK]) for t in e.source]
            ids = [
                src[UNK] if not t.startswith("<") and rng.random() < cfg.word_dropout else i
                for t, i in zip(e.source, ids, strict=True)
            ]
            source[b, : len(ids)] = torch.tensor(ids)
            out = [tgt[t] for t in e.target]
            target_in[b, : len(out) + 1] = torch.tensor([tgt[BOS], *out])
            target_out[b, : len(out) + 1] = torch.tensor([*out, tgt[EOS]])
        lengths = torch.tensor([len(e.source) for e in chunk])
        yield source, lengths, target_in, target_out


def export(model: Seq2Seq, role: Role, source_vocab: list[str], target_vocab: list[str], path: Path) -> None:
    """The weights as `sim.language.reader.Reader` reads them (float32, no pickles)."""
    p = {k: v.detach().numpy().astype(np.float32) for k, v in model.state_dict().items()}
    arrays = {
        "embed": p["embed.weight"],
        "enc_w_ih": p["encoder.weight_ih_l0"],
        "enc_w_hh": p["encoder.weight_hh_l0"],
        "enc_b_ih": p["encoder.bias_ih_l0"],
        "enc_b_hh": p["encoder.bias_hh_l0"],
        "enc_w_ih_r": p["encoder.weight_ih_l0_reverse"],
        "enc_w_hh_r": p["encoder.weight_hh_l0_reverse"],
        "enc_b_ih_r": p["encoder.bias_ih_l0_reverse"],
        "enc_b_hh_r": p["encoder.bias_hh_l0_reverse"],
        "bridge_w": p["bridge.weight"],
        "bridge_b": p["bridge.bias"],
        "out_embed": p["out_embed.weight"],
        "dec_w_ih": p["decoder.weight_ih"],
        "dec_w_hh": p["decoder.weight_hh"],
        "dec_b_ih": p["decoder.bias_ih"],
        "dec_b_hh": p["decoder.bias_hh"],
        "attn_w": p["attn.weight"],
        "out_w": p["out.weight"],
        "out_b": p["out.bias"],
    }
    np.savez_compressed(
        path,
        **arrays,
        vocab_role=np.array([role.value]),
        vocab_source=np.array(source_vocab),
        vocab_target=np.array(target_vocab),
    )


def train_reader(role: Role, examples: Sequence[Example], cfg: Config, out: Path) -> dict[str, Any]:
    # One thread: the batches are small and sequential in the decoder, and a second thread fighting
    # for the 2-core machine made an epoch 10x slower (46 s against 4.1 s).
    torch.set_num_threads(1)
    torch.manual_seed(cfg.seed)
    rng = random.Random(cfg.seed)
    counts = Counter(t for e in examples for t in e.source)
    source_vocab = FIXED_SOURCE + sorted(t for t in counts if t not in FIXED_SOURCE)
    target_vocab = output_vocabulary(role)
    src = {t: i for i, t in enumerate(source_vocab)}
    tgt = {t: i for i, t in enumerate(target_vocab)}
    model = Seq2Seq(len(source_vocab), len(target_vocab), cfg)
    optimizer = torch.optim.Adam(model.parameters(), lr=cfg.lr)
    schedule = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, T_max=cfg.epochs)
    loss_fn = nn.CrossEntropyLoss(ignore_index=0)
    history = []
    bar = tqdm(range(cfg.epochs), desc=f"train {role.value} reader", unit="epoch")
    for _ in bar:
        model.train()
        total, n = 0.0, 0
        for source, lengths, target_in, target_out in _batches(examples, src, tgt, cfg, rng):
            logits = model(source, lengths, target_in)
            loss = loss_fn(logits.reshape(-1, logits.shape[-1]), target_out.reshape(-1))
            optimizer.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(model.parameters(), 5.0)
            optimizer.step()
            total += loss.item() * len(source)
            n += len(source)
        schedule.step()
        history.append(total / n)
        bar.set_postfix(loss=f"{total / n:.4f}")
    model.eval()
    export(model, role, source_vocab, target_vocab, out / f"{role.value}.npz")
    return {"examples": len(examples), "source_vocabulary": len(source_vocab), "loss": history}


def train(bench: Benchmark, cfg: Config, out: Path) -> dict[str, Any]:
    """Both readers into `out` (commander.npz, driver.npz, training.json)."""
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    silver = selfplay_examples(bench, cfg.selfplay_trials, cfg.seed)
    report: dict[str, Any] = {"config": cfg.__dict__, "readers": {}}
    for role in Role:
        hand = hand_examples(bench, role)
        commander = role == Role.COMMANDER
        rules = silver[role] + (vocabulary_examples(cfg.seed) if commander else [])
        built = paraphrased_examples(cfg.seed, cfg.paraphrases) if commander else []
        report["readers"][role.value] = {
            "hand_labelled": len(hand),
            "rules_labelled": len(rules),
            "paraphrased": len(built),
            **train_reader(role, hand + rules + built, cfg, out),
        }
    report["seconds"] = round(time.perf_counter() - t0, 1)
    (out / "training.json").write_text(json.dumps(report, indent=2))
    return report

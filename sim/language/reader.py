"""The trained reader: a dialog turn, with the turn before it, into what it means.

A small sequence-to-sequence network (word embeddings, a bidirectional GRU over the words, a GRU
decoder with attention) writes a turn's meaning (`meaning.Program` for a Commander turn, a fact
set for a Driver turn) as a sequence of tokens: an op or fact kind, then each of its fields. The
decoder is held to that grammar, so whatever it writes is a well-formed meaning. It is trained with
torch by `robotslang train language` (models/language.py) on the train split's hand-labelled
turns; this module runs it in numpy, so the simulator, the agents and the server need no torch.

Words are spelling-corrected (`vocab.words`), a turn's size said in any of the rules' words is one
word ("slightly", "sharply"); distances are put in steps ("35 cm" is 5 steps) and
angles in words ("45 degrees" is `deg45`); the turn's other numbers become `<num0>`, `<num1>`, ...
and a field can say "the first number" (`#0`), so counts never seen in training are still read.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from enum import StrEnum
from functools import cache
from pathlib import Path

import numpy as np

from sim.language.meaning import (
    CLAUSE_FIELDS,
    FACT_FIELDS,
    LABELS,
    SIDES,
    Clause,
    FactForm,
    FactKind,
    Op,
    Program,
    Value,
)
from sim.language.vocab import SHARP_WORDS, SLIGHT_WORDS, number, words

STEP_M = 0.07  # one forward move
MAX_CONTEXT = 12  # words of the turn before that the reader sees
MAX_NUMBERS = 4
MAX_OUTPUT = 48
STRANGE = 0.5  # this share of a turn's words or more unknown to the reader: it is not understood ("go leftish")
SHIPPED_DIR = Path(__file__).with_name("reader")

PAD, UNK, SEP, BOS, EOS = "<pad>", "<unk>", "<sep>", "<bos>", "<eos>"
OBJECTS = ("jar", "mug", "paddle")
_STEPS: tuple[Value, ...] = (None, *(f"#{k}" for k in range(MAX_NUMBERS)), *range(1, 21))
_NTH: tuple[Value, ...] = (*(f"#{k}" for k in range(MAX_NUMBERS)), *range(1, 6))
_BOOL: tuple[Value, ...] = (True, False)


class Role(StrEnum):
    """Whose turn is read: the Commander's (a program) or the Driver's (facts)."""

    COMMANDER = "commander"
    DRIVER = "driver"


# Each field's possible values: the grammar the decoder is held to.
DOMAINS: dict[str, dict[str, tuple[Value, ...]]] = {
    Op.TURN: {"eighths": (-3, -2, -1, 1, 2, 3, 4)},
    Op.FORWARD: {"steps": _STEPS, "until": (None, "wall", *LABELS)},
    Op.FOLLOW: {"label": LABELS},
    Op.OPENING: {"side": ("left", "right"), "nth": _NTH},
    Op.BACK: {"place": ("start", "turn", "previous"), "steps": _STEPS},
    Op.TARGET: {"label": OBJECTS},
    Op.EXPECT: {"label": LABELS, "side": SIDES},
    Op.ASK: {
        "question": ("view", "side", "is_there", "look_around", "status", "other"),
        "side": (None, *SIDES),
        "label": (None, *LABELS),
    },
    Op.ANSWER: {"value": ("yes", "no")},
    Op.STOP: {"claim": _BOOL},
    Op.REJECT: {},
    Op.UNCLEAR: {},
    FactKind.LABEL: {"label": LABELS, "side": SIDES, "distance": ("near", "far", "any"), "negated": _BOOL},
    FactKind.EDGE: {"side": SIDES, "negated": _BOOL},
    FactKind.CORRIDOR: {"side": SIDES},
    FactKind.CORNER: {"side": SIDES},
    FactKind.DEAD_END: {},
    FactKind.NEXT_TO: {"label": LABELS, "other": LABELS},
    FactKind.ANSWER: {"value": ("yes", "no")},
    FactKind.QUESTION: {},
    FactKind.CLAIM: {},
}
HEADS: dict[Role, tuple[str, ...]] = {Role.COMMANDER: tuple(Op), Role.DRIVER: tuple(FactKind)}


def value_token(field: str, value: Value) -> str:
    return f"{field}:{'null' if value is None else str(value).lower()}"


def output_vocabulary(role: Role) -> list[str]:
    """Every token the decoder may write for `role`, in a fixed order."""
    tokens = [PAD, BOS, EOS, *HEADS[role]]
    for head in HEADS[role]:
        for field, values in DOMAINS[head].items():
            tokens += [t for t in (value_token(field, v) for v in values) if t not in tokens]
    return tokens


_TURNS = frozenset({"turns", "times"})  # "two right turns", "left 3 times"
_UNIT = re.compile(r"^(cm|centimeters?|centimetres?|m|meters?|metres?|deg|degrees?)$")


@dataclass(frozen=True)
class Count:
    """A number a turn names: in steps for distances (its angles are no counts), the words that
    said it ("3", "35 cm"), and whether it may count steps: not where it counts turns ("two right
    turns", "left 3 times", "an eighth of a turn": spelling correction reads "eighth" as "eight"),
    nor a bare "one" ("the next one")."""

    steps: int
    said: str
    of_steps: bool


def _read_numbers(text: str) -> tuple[list[str], list[Count]]:
    """`normalize`'s words, and the counts the turn names."""
    ws = words(text.replace("°", " degrees "))
    out: list[str] = []
    counts: list[Count] = []
    for i, w in enumerate(ws):
        found = number(w)
        if found is None:
            if not _UNIT.match(w) or not out or not out[-1].startswith(("<num", "deg")):
                # A turn's size said in any of the rules' words reads as one word.
                out.append("slightly" if w in SLIGHT_WORDS else "sharply" if w in SHARP_WORDS else w)
            continue
        n = found
        # The word after a number is its unit only where it is one ("5 more steps" is not 5 metres).
        unit = ws[i + 1] if i + 1 < len(ws) and _UNIT.match(ws[i + 1]) else ""
        if unit.startswith("deg") or (n in (45, 90, 135, 180) and not unit.startswith(("c", "m"))):
            out.append(f"deg{min((45, 90, 135, 180), key=lambda a: abs(a - n))}")
            continue
        if unit.startswith("c"):
            n = max(1, round(n / 100 / STEP_M))
        elif unit.startswith("m"):
            n = max(1, round(n / STEP_M))
        numbers = [c.steps for c in counts]
        if n not in numbers:
            after = ws[i + 1 : i + 4]
            of_turns = bool(_TURNS.intersection(after[:2])) or after == ["of", "a", "turn"]
            pronoun = w == "one" and not unit and after[:1] not in (["step"], ["steps"])  # "the next one"
            counts.append(Count(n, f"{w} {unit}".strip(), not of_turns and not pronoun))
            numbers.append(n)
        k = numbers.index(n)
        out.append(f"<num{k}>" if k < MAX_NUMBERS else "<num>")
    return out, counts


def normalize(text: str) -> tuple[list[str], list[int]]:
    """The turn's words for the reader, and the numbers it names (in steps for distances)."""
    out, counts = _read_numbers(text)
    return out, [c.steps for c in counts]


def counts(text: str) -> list[Count]:
    """The counts a turn names, in the order first named."""
    return _read_numbers(text)[1]


def source_tokens(text: str, before: tuple[str, str] | None) -> tuple[list[str], list[int]]:
    """The reader's input: the turn before (its speaker and last words) and the turn itself."""
    own, numbers = normalize(text)
    if before is None:
        return [SEP, *own], numbers
    speaker, said = before
    context = ["<n>" if w.startswith("<num") else w for w in normalize(said)[0]][-MAX_CONTEXT:]
    return [f"<{speaker}>", *context, SEP, *own], numbers


def encode_meaning(role: Role, meaning: Sequence[Clause] | frozenset[FactForm], numbers: list[int]) -> list[str]:
    """A meaning as the decoder writes it (facts in a fixed order); numbers named in the turn as #k."""
    items: list[Clause | FactForm] = (
        list(meaning) if isinstance(meaning, Sequence) else sorted(meaning, key=lambda f: str(f.to_json()))
    )
    out: list[str] = []
    for item in items:
        head, fields = (
            (item.op, CLAUSE_FIELDS[item.op]) if isinstance(item, Clause) else (item.kind, FACT_FIELDS[item.kind])
        )
        out.append(str(head))
        for field, value in zip(fields, item.args, strict=True):
            if field in ("steps", "nth") and isinstance(value, int) and value in numbers[:MAX_NUMBERS]:
                value = f"#{numbers.index(value)}"
            out.append(value_token(field, value))
    return out


def _value(token: str, field: str, numbers: list[int]) -> Value:
    raw = token.removeprefix(f"{field}:")
    if raw == "null":
        return None
    if raw in ("true", "false"):
        return raw == "true"
    if raw.startswith("#"):
        k = int(raw[1:])
        return numbers[k] if k < len(numbers) else None
    if raw.lstrip("-").isdigit():
        return int(raw)
    return raw


def decode_meaning(role: Role, tokens: Sequence[str], numbers: list[int]) -> Program | frozenset[FactForm]:
    """The decoder's tokens back into a meaning (the grammar made them well formed)."""
    clauses: list[Clause] = []
    facts: set[FactForm] = set()
    i = 0
    while i < len(tokens):
        head = tokens[i]
        fields = list(DOMAINS[head])
        values = {f: _value(t, f, numbers) for f, t in zip(fields, tokens[i + 1 : i + 1 + len(fields)], strict=True)}
        i += 1 + len(fields)
        if role == Role.COMMANDER:
            clauses.append(Clause.of(Op(head), **values))
        else:
            facts.add(FactForm.of(FactKind(head), **values))
    return tuple(clauses) if role == Role.COMMANDER else frozenset(facts)


def _sigmoid(x: np.ndarray) -> np.ndarray:
    return np.asarray(1.0 / (1.0 + np.exp(-x)))


def gru_step(
    x: np.ndarray, h: np.ndarray, w_ih: np.ndarray, w_hh: np.ndarray, b_ih: np.ndarray, b_hh: np.ndarray
) -> np.ndarray:
    """One step of torch's GRU (gates r, z, n in that order)."""
    gi = w_ih @ x + b_ih
    gh = w_hh @ h + b_hh
    size = h.shape[0]
    r = _sigmoid(gi[:size] + gh[:size])
    z = _sigmoid(gi[size : 2 * size] + gh[size : 2 * size])
    n = np.tanh(gi[2 * size :] + r * gh[2 * size :])
    return np.asarray((1 - z) * n + z * h)


@dataclass(frozen=True)
class Reading:
    """What the reader made of a turn, with how sure it was (the mean probability of its tokens)."""

    meaning: Program | frozenset[FactForm]
    confidence: float
    strange_lead: bool = False  # its first word is one the reader never met (a verb it cannot know)


class Reader:
    """One role's trained reader, from the weights `models/language.py` exports."""

    def __init__(self, path: Path) -> None:
        with np.load(path, allow_pickle=False) as saved:
            self.w = {k: np.asarray(saved[k], dtype=np.float64) for k in saved.files if not k.startswith("vocab_")}
            self.role = Role(str(saved["vocab_role"][0]))
            self.source = [str(t) for t in saved["vocab_source"]]
            self.target = [str(t) for t in saved["vocab_target"]]
        self._source_index = {t: i for i, t in enumerate(self.source)}
        if len(self._source_index) != len(self.source):
            raise ValueError(f"{path}: a word appears twice in the reader's vocabulary")
        self._target_index = {t: i for i, t in enumerate(self.target)}
        self._masks = self._grammar_masks()

    def _grammar_masks(self) -> dict[str, np.ndarray]:
        """Allowed next tokens: `start` (a head or the end) and, per head and field, its values."""
        masks: dict[str, np.ndarray] = {}
        start = np.full(len(self.target), -np.inf)
        for t in (*HEADS[self.role], EOS):
            start[self._target_index[t]] = 0.0
        masks["start"] = start
        for head in HEADS[self.role]:
            for field, values in DOMAINS[head].items():
                mask = np.full(len(self.target), -np.inf)
                for v in values:
                    mask[self._target_index[value_token(field, v)]] = 0.0
                masks[f"{head}.{field}"] = mask
        return masks

    def _encode(self, tokens: list[str]) -> tuple[np.ndarray, np.ndarray]:
        w = self.w
        ids = [self._source_index.get(t, self._source_index[UNK]) for t in tokens]
        xs = w["embed"][ids]
        hidden = w["enc_w_hh"].shape[1]
        fwd, h = [], np.zeros(hidden)
        for x in xs:
            h = gru_step(x, h, w["enc_w_ih"], w["enc_w_hh"], w["enc_b_ih"], w["enc_b_hh"])
            fwd.append(h)
        bwd, h = [], np.zeros(hidden)
        for x in xs[::-1]:
            h = gru_step(x, h, w["enc_w_ih_r"], w["enc_w_hh_r"], w["enc_b_ih_r"], w["enc_b_hh_r"])
            bwd.append(h)
        states = np.concatenate([np.stack(fwd), np.stack(bwd[::-1])], axis=1)
        start = np.tanh(w["bridge_w"] @ np.concatenate([fwd[-1], bwd[-1]]) + w["bridge_b"])
        return states, start

    def decode(self, tokens: list[str]) -> tuple[list[str], float]:
        """The decoder's greedy tokens for the source tokens, under the grammar, and their mean probability."""
        w = self.w
        states, h = self._encode(tokens)
        keys = states @ w["attn_w"].T  # (T, D): attention scores are keys @ h
        context = np.zeros(states.shape[1])
        prev = self._target_index[BOS]
        out: list[str] = []
        pending: list[str] = []  # the fields still to write for the last head
        probs: list[float] = []
        for _ in range(MAX_OUTPUT):
            x = np.concatenate([w["out_embed"][prev], context])
            h = gru_step(x, h, w["dec_w_ih"], w["dec_w_hh"], w["dec_b_ih"], w["dec_b_hh"])
            scores = keys @ h
            attn = np.exp(scores - scores.max())
            attn /= attn.sum()
            context = attn @ states
            logits = w["out_w"] @ np.concatenate([h, context]) + w["out_b"]
            logits = logits + self._masks[pending[0] if pending else "start"]
            p = np.exp(logits - logits.max())
            p /= p.sum()
            prev = int(np.argmax(p))
            probs.append(float(p[prev]))
            token = self.target[prev]
            if pending:
                pending.pop(0)
            elif token == EOS:
                break
            else:
                pending = [f"{token}.{field}" for field in DOMAINS[token]]
            out.append(token)
        return complete(out, self.role), float(np.mean(probs))

    def read(self, text: str, before: tuple[str, str] | None = None) -> Reading:
        """`before`: the turn before this one, as (speaker "c" or "d", its text), if any. A turn
        half or more of words the reader never met is not guessed at: a Commander's is `unclear`, a
        Driver's states nothing."""
        tokens, numbers = source_tokens(text, before)
        own = tokens[tokens.index(SEP) + 1 :]
        if own and sum(t not in self._source_index for t in own) >= STRANGE * len(own):
            return Reading((Clause.of(Op.UNCLEAR),) if self.role == Role.COMMANDER else frozenset(), 0.0)
        out, confidence = self.decode(tokens)
        return Reading(
            decode_meaning(self.role, out, numbers), confidence, bool(own) and own[0] not in self._source_index
        )


def complete(tokens: list[str], role: Role) -> list[str]:
    """The tokens up to the last head written with all its fields."""
    whole: list[str] = []
    i = 0
    heads = set(HEADS[role])
    while i < len(tokens) and tokens[i] in heads:
        n = len(DOMAINS[tokens[i]])
        if i + n >= len(tokens):  # cut off by MAX_OUTPUT before its last field
            break
        whole += tokens[i : i + 1 + n]
        i += 1 + n
    return whole


@cache
def shipped(role: Role) -> Reader:
    """The reader shipped in the package, loaded once per process."""
    return Reader(SHIPPED_DIR / f"{role.value}.npz")

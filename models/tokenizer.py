"""Dialog histories to token ids, as the NDH seq2seq reads them.

Each message becomes `<COM>` (Commander, role `oracle`) or `<DRI>` (Driver, role `navigator`)
followed by its lower-cased words and punctuation; the history ends with `<TAR>` and the target
word. Only the most recent `max_tokens` tokens are kept: the end of a dialog is what says where
to go next.
"""

from __future__ import annotations

import json
import re
from collections import Counter
from collections.abc import Iterable, Sequence

PAD, UNK = "<PAD>", "<UNK>"
COMMANDER, DRIVER, TARGET = "<COM>", "<DRI>", "<TAR>"
SPECIALS = (PAD, UNK, COMMANDER, DRIVER, TARGET)
MAX_TOKENS = 100

# Both the benchmark's role names and the web UI's map onto the two speaker tokens.
SPEAKER_TOKEN = {"oracle": COMMANDER, "commander": COMMANDER, "navigator": DRIVER, "driver": DRIVER}

_WORD = re.compile(r"[a-z0-9]+|[^\sa-z0-9]")


def split_words(text: str) -> list[str]:
    """'Turn LEFT, then go!' -> ['turn', 'left', ',', 'then', 'go', '!']."""
    return _WORD.findall(text.lower())


def dialog_tokens(dialog: Iterable[tuple[str, str]], target: str) -> list[str]:
    """(role, message) pairs and the target word to the full token sequence (not truncated)."""
    tokens: list[str] = []
    for role, message in dialog:
        try:
            tokens.append(SPEAKER_TOKEN[role])
        except KeyError:
            raise ValueError(
                f"unknown speaker role {role!r} in dialog; expected one of {', '.join(sorted(SPEAKER_TOKEN))}"
            ) from None
        tokens.extend(split_words(message))
    tokens.append(TARGET)
    tokens.extend(split_words(target))
    return tokens


class Tokenizer:
    """A fixed vocabulary (from the training fold) and the truncation rule."""

    def __init__(self, vocab: Sequence[str], max_tokens: int = MAX_TOKENS):
        if tuple(vocab[: len(SPECIALS)]) != SPECIALS:
            raise ValueError(f"vocabulary must start with the special tokens {SPECIALS}")
        self.vocab = list(vocab)
        self.index = {word: i for i, word in enumerate(self.vocab)}
        if len(self.index) != len(self.vocab):
            raise ValueError("vocabulary has duplicate words")
        self.max_tokens = max_tokens

    @classmethod
    def from_dialogs(
        cls, dialogs: Iterable[tuple[Iterable[tuple[str, str]], str]], min_count: int = 1, max_tokens: int = MAX_TOKENS
    ) -> Tokenizer:
        """Vocabulary of every word seen at least `min_count` times in (dialog, target) pairs."""
        counts: Counter[str] = Counter()
        for dialog, target in dialogs:
            counts.update(t for t in dialog_tokens(dialog, target) if t not in SPECIALS)
        words = sorted((w for w, n in counts.items() if n >= min_count), key=lambda w: (-counts[w], w))
        return cls(list(SPECIALS) + words, max_tokens)

    def __len__(self) -> int:
        return len(self.vocab)

    def encode(self, dialog: Iterable[tuple[str, str]], target: str) -> list[int]:
        """Ids of the most recent `max_tokens` tokens; unknown words become `<UNK>`."""
        tokens = dialog_tokens(dialog, target)[-self.max_tokens :]
        return [self.index.get(t, self.index[UNK]) for t in tokens]

    def to_json(self) -> str:
        return json.dumps({"vocab": self.vocab, "max_tokens": self.max_tokens})

    @classmethod
    def from_json(cls, text: str) -> Tokenizer:
        data = json.loads(text)
        return cls(data["vocab"], data["max_tokens"])

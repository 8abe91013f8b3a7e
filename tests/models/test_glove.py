"""Word embeddings initialised from a GloVe text file."""

from __future__ import annotations

import pytest
import torch

from models.tokenizer import Tokenizer
from models.train import TrainConfig, load_glove, make_agent


def test_vocabulary_words_get_their_glove_vectors_and_the_dimension_follows(tmp_path):
    tok = Tokenizer.from_dialogs([([("oracle", "turn left at the red wall")], "mug")])
    glove = tmp_path / "glove.txt"
    glove.write_text("turn 0.1 0.2 0.3\nred -1 0 1\nunrelated 5 5 5\n")
    agent = make_agent(TrainConfig(glove=str(glove)), tok, obs_features=157)
    emb = agent.embedding.weight.detach()
    assert emb.shape == (len(tok), 3)
    assert torch.allclose(emb[tok.index["turn"]], torch.tensor([0.1, 0.2, 0.3]))
    assert torch.allclose(emb[tok.index["red"]], torch.tensor([-1.0, 0.0, 1.0]))
    assert (emb[0] == 0).all()  # padding


def test_a_file_that_is_not_glove_is_named(tmp_path):
    tok = Tokenizer.from_dialogs([([("oracle", "turn left")], "mug")])
    bad = tmp_path / "notes.txt"
    bad.write_text("turn left here\n")
    with pytest.raises(ValueError, match="notes.txt:1"):
        load_glove(bad, tok)
    empty = tmp_path / "other.txt"
    empty.write_text("zebra 1 2\n")
    with pytest.raises(ValueError, match="no vectors for any vocabulary word"):
        load_glove(empty, tok)

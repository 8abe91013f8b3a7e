"""The dialog tokenizer: speaker tokens, target, truncation, vocabulary from training only."""

from __future__ import annotations

import pytest

from models.tokenizer import COMMANDER, DRIVER, TARGET, Tokenizer, dialog_tokens, split_words

DIALOG = [("oracle", "Turn LEFT at the red wall, then go!"), ("navigator", "ok, I see a Jar?")]


def test_words_are_lower_cased_and_punctuation_is_its_own_token():
    assert split_words("Turn LEFT, then go!") == ["turn", "left", ",", "then", "go", "!"]


def test_each_message_is_prefixed_by_its_speaker_and_the_target_comes_last():
    tokens = dialog_tokens(DIALOG, "mug")
    assert tokens[0] == COMMANDER
    assert tokens[tokens.index("ok") - 1] == DRIVER
    assert tokens[-2:] == [TARGET, "mug"]
    # The web UI's role names map to the same speakers as the benchmark's.
    ui = dialog_tokens([("commander", "Turn LEFT at the red wall, then go!"), ("driver", "ok, I see a Jar?")], "mug")
    assert ui == tokens


def test_unknown_role_is_an_error_naming_it():
    with pytest.raises(ValueError, match="'robot'"):
        dialog_tokens([("robot", "beep")], "jar")


def test_only_the_most_recent_tokens_are_kept():
    tok = Tokenizer.from_dialogs([([("oracle", " ".join(f"w{i}" for i in range(300)))], "jar")], max_tokens=100)
    ids = tok.encode([("oracle", " ".join(f"w{i}" for i in range(300)))], "jar")
    assert len(ids) == 100
    assert [tok.vocab[i] for i in ids[-3:]] == ["w299", TARGET, "jar"]
    assert tok.vocab[ids[0]] == "w202"


def test_words_outside_the_training_vocabulary_become_unk():
    tok = Tokenizer.from_dialogs([(DIALOG, "mug")])
    ids = tok.encode([("oracle", "turn towards the paddle")], "mug")
    words = [tok.vocab[i] for i in ids]
    assert words == [COMMANDER, "turn", "<UNK>", "the", "<UNK>", TARGET, "mug"]


def test_min_count_drops_rare_words_and_json_round_trips():
    tok = Tokenizer.from_dialogs([(DIALOG, "mug"), ([("oracle", "turn right")], "jar")], min_count=2)
    assert "turn" in tok.index and "red" not in tok.index
    again = Tokenizer.from_json(tok.to_json())
    assert again.vocab == tok.vocab and again.encode(DIALOG, "mug") == tok.encode(DIALOG, "mug")

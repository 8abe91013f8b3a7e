"""The learned LDH localizer: checkpoints that are not ours are refused clearly, an untrained
model is exactly the colour baseline, and `train ldh` writes a checkpoint `eval ldh` reads."""

from __future__ import annotations

import json

import pytest
import torch
from typer.testing import CliRunner

from app.cli import root
from models.ldh import LDHConfig, Localizer, save
from tests.sim.helpers import export_folder, exported, said


def eval_learned(bench, checkpoint, agents="learned"):
    args = ["eval", "ldh", "--benchmark", str(bench), "--split", "val_seen", "--agent", agents, "--json"]
    if checkpoint is not None:
        args += ["--checkpoint", str(checkpoint)]
    return CliRunner().invoke(root, args)


@pytest.fixture
def bench(tmp_path):
    return export_folder(tmp_path / "export", [exported(0, [1.4, 0.7, 0.0]), exported(1, [0.6, 1.5, 1.0])])


def test_a_file_that_is_not_a_checkpoint_is_refused(bench, tmp_path):
    garbage = tmp_path / "best.pt"
    garbage.write_bytes(b"\x89PNG not a checkpoint")
    result = eval_learned(bench, garbage)
    assert result.exit_code == 2 and "not a checkpoint" in said(result)


def test_another_models_checkpoint_and_a_missing_file_are_refused(bench, tmp_path):
    other = tmp_path / "ndh.pt"
    torch.save({"format": "robotslang-ndh", "state": {}}, other)
    result = eval_learned(bench, other)
    assert result.exit_code == 2 and "not an LDH checkpoint" in said(result)
    result = eval_learned(bench, tmp_path / "absent.pt")
    assert result.exit_code == 2 and "no such checkpoint" in said(result)
    result = eval_learned(bench, None)
    assert result.exit_code == 2 and "needs --checkpoint" in said(result)


def test_an_untrained_model_is_the_colour_baseline(bench, tmp_path):
    path = tmp_path / "zero.pt"
    save(Localizer(dropout=0.5, prior=True), LDHConfig(), path)
    result = eval_learned(bench, path, agents="colours,learned")
    assert result.exit_code == 0, result.output
    agents = json.loads(result.output)["agents"]
    assert agents["learned"] == agents["colours"]


@pytest.mark.slow
@pytest.mark.benchmark_data
def test_train_ldh_writes_a_checkpoint_chosen_on_val_seen(benchmark_path, tmp_path):
    out = tmp_path / "run"
    result = CliRunner().invoke(
        root, ["train", "ldh", "--benchmark", str(benchmark_path), "--seed", "0", "--out", str(out), "--epochs", "2"]
    )
    assert result.exit_code == 0, result.output
    history = json.loads((out / "history.json").read_text())
    best = min(history["history"], key=lambda h: h["val_td"])
    assert history["best"]["epoch"] == best["epoch"] and (out / "best.pt").is_file()
    result = CliRunner().invoke(
        root,
        [
            "eval",
            "ldh",
            "--benchmark",
            str(benchmark_path),
            "--split",
            "val_seen",
            "--agent",
            "learned",
            "--checkpoint",
            str(out / "best.pt"),
            "--json",
        ],
    )
    assert result.exit_code == 0, result.output
    assert json.loads(result.output)["agents"]["learned"]["td_mean"] == pytest.approx(best["val_td"])

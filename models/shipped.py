"""The NDH Driver that ships inside the package (`models/checkpoints/ndh_driver.pt`), so a fresh
install seats `agent:seq2seq` and `eval ndh` scores a Driver without any setting.

`ship(RUN/best.pt)` writes it: the weights a Driver plays with (the averaged ones where the
variant averages), the tokenizer and the configurations, without the optimizer state and the
raw training weights, which only a resumed training needs. Its model card: docs/model_card_ndh.md.

    python -m models.shipped runs/ship/best.pt
"""

from __future__ import annotations

import sys
from pathlib import Path

SHIPPED_CHECKPOINT = Path(__file__).parent / "checkpoints" / "ndh_driver.pt"


def default_checkpoint() -> Path | None:
    """The shipped checkpoint, or None where this copy of the package has none."""
    return SHIPPED_CHECKPOINT if SHIPPED_CHECKPOINT.is_file() else None


def ship(source: str | Path, dest: str | Path = SHIPPED_CHECKPOINT) -> Path:
    """Write the playing part of the checkpoint `source` to `dest`; it loads with `load_agent`."""
    import torch

    from models.train import load_agent

    _, _, ckpt = load_agent(source)  # refuses a file that is not a Driver checkpoint
    slim = {key: ckpt[key] for key in ("agent_config", "tokenizer", "train_config", "iteration", "history", "best")}
    slim["state_dict"] = ckpt.get("eval_state_dict") or ckpt["state_dict"]
    slim["eval_state_dict"] = None
    dest = Path(dest)
    dest.parent.mkdir(parents=True, exist_ok=True)
    tmp = dest.with_suffix(".tmp")
    torch.save(slim, tmp)
    tmp.replace(dest)
    return dest


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python -m models.shipped RUN/best.pt")
    path = ship(sys.argv[1])
    print(f"{path} ({path.stat().st_size / 1e6:.1f} MB)")

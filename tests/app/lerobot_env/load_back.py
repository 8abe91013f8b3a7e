"""Run by the lerobot venv's Python (`make lerobot-venv`), never the project's: load a LeRobot
dataset folder with lerobot's own `LeRobotDataset` and report what it serves, item by item.

    load_back.py DATASET_DIR OUT_DIR

writes OUT_DIR/items.json (the dataset's counts and every item's scalar and text fields) and
OUT_DIR/<video key>.npy (every item's image as LeRobot serves it, channels first, scaled to uint8).
"""

import json
import sys
from pathlib import Path

import numpy as np
from lerobot.datasets.lerobot_dataset import LeRobotDataset


def main(root: Path, out: Path) -> None:
    dataset = LeRobotDataset("robotslang/export", root=root)
    items = [dataset[i] for i in range(len(dataset))]
    video_keys = list(dataset.meta.video_keys)
    for key in video_keys:
        images = np.stack([(item[key].numpy() * 255).round().astype(np.uint8) for item in items])
        np.save(out / f"{key}.npy", images)
    fields = [k for k in items[0] if k not in video_keys]
    report = {
        "num_frames": dataset.num_frames,
        "num_episodes": dataset.num_episodes,
        "fps": dataset.fps,
        "video_keys": video_keys,
        "items": [{k: (item[k] if isinstance(item[k], str) else item[k].tolist()) for k in fields} for item in items],
    }
    (out / "items.json").write_text(json.dumps(report))


if __name__ == "__main__":
    main(Path(sys.argv[1]), Path(sys.argv[2]))

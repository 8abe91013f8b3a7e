"""What the benchmarks measure beside their figures: percentiles, resident memory, the machine's load."""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np


def percentile(values: Sequence[float] | np.ndarray, q: float) -> float:
    """The `q`th percentile (numpy's linear interpolation); NaN where nothing was measured."""
    return float(np.percentile(values, q)) if len(values) else float("nan")


def rss_mb(pid: int) -> float:
    """A process's resident memory, MiB (its `VmRSS`); OSError or StopIteration once it is gone."""
    status = Path(f"/proc/{pid}/status").read_text().splitlines()
    return next(int(line.split()[1]) / 1024 for line in status if line.startswith("VmRSS:"))


def load_average() -> str:
    """The machine's 1, 5 and 15 minute load averages, as printed beside a figure taken under them."""
    return ", ".join(f"{x:.2f}" for x in os.getloadavg())

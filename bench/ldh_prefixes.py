"""The lengths of the LDH inputs that rule prefix-v1 cuts, per split: printed, and as a histogram.

python -m bench.ldh_prefixes --benchmark PATH [--png docs/img/ldh_prefix_lengths.png]
"""

from __future__ import annotations

import argparse
import os
from collections import Counter

from sim.tasks.benchmark import Benchmark, Split
from sim.tasks.ldh import CUT_RULE, Variant, load_split


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--benchmark", default=os.environ.get("ROBOTSLANG_BENCHMARK"), required=False)
    parser.add_argument("--png", default=None)
    args = parser.parse_args()
    bench = Benchmark(args.benchmark)
    lengths = {}
    for split in Split:
        prefix = load_split(bench, split, Variant.PREFIX)
        full = load_split(bench, split, Variant.FULL)
        lengths[split] = [len(p.dialog) for p in prefix]
        share = sum(len(p.dialog) for p in prefix) / sum(len(f.dialog) for f in full)
        print(
            f"{split}: n={len(prefix)} prefix turns mean {sum(lengths[split]) / len(prefix):.2f}, "
            f"median {sorted(lengths[split])[len(prefix) // 2]}, max {max(lengths[split])}; "
            f"{share:.0%} of the first sub-dialogs' turns; counts {dict(sorted(Counter(lengths[split]).items()))}"
        )
    if args.png:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(6, 3.2))
        top = max(max(v) for v in lengths.values())
        ax.hist(list(lengths.values()), bins=range(0, top + 2), label=list(lengths), stacked=True, align="left")
        ax.set_xlabel(f"turns in the LDH input ({CUT_RULE})")
        ax.set_ylabel("trials")
        ax.legend()
        fig.tight_layout()
        fig.savefig(args.png, dpi=110)
        print(f"histogram -> {args.png}")


if __name__ == "__main__":
    main()

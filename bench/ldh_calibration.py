"""Fit the dialog localizer's calibration on the train split and print it as `FITTED`.

python -m bench.ldh_calibration --benchmark PATH

Paste the printed line over `FITTED` in sim/language/calibration.py. Only train is read.
"""

from __future__ import annotations

import argparse
import os

from sim.language.calibration import fit
from sim.tasks.benchmark import Benchmark, Split
from sim.tasks.ldh import load_split
from sim.tasks.ldh_dialog import calibration_records


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--benchmark", default=os.environ.get("ROBOTSLANG_BENCHMARK"), required=False)
    args = parser.parse_args()
    bench = Benchmark(args.benchmark)
    records = calibration_records(bench, load_split(bench, Split.TRAIN))
    fitted = fit(records)
    counts = {kind: sum(r.kind == kind for r in records) for kind in fitted.log_ratio}
    print(f"# facts per kind: {', '.join(f'{k.value} {n}' for k, n in counts.items())}")
    body = ", ".join(f"Evidence.{k.name}: {v}" for k, v in fitted.log_ratio.items())
    print(f"FITTED = Calibration({{{body}}})")


if __name__ == "__main__":
    main()

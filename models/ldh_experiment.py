"""`robotslang experiment ldh`: ablations on val_seen, 3 seeds, then test once, with tests.

Every configuration is trained with each seed and chosen on val_seen; only the main
configuration's checkpoints are then run on test, once, beside the baselines. The learned
model is compared with `center` and with the language baseline `colours` by paired t-tests on
the per-instance TD (seeds averaged), corrected with Benjamini-Yekutieli (models/stats.py).
The results table and error plots are written into docs/ldh.md between its markers.
"""

from __future__ import annotations

import json
import subprocess
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from models.ldh import LDHConfig, load_localizer, train
from models.stats import paired_tests, per_instance
from sim.tasks.benchmark import Benchmark
from sim.tasks.ldh import CUT_RULE, HUMANS_TD_M, Variant, load_split
from sim.tasks.ldh_eval import BASELINES, MazeContexts, evaluate, summarize, summarize_agent, write_csv

MAIN = LDHConfig()
ABLATIONS = {  # name -> the main configuration with one ingredient added (+) or removed (-)
    "learned": MAIN,
    "+ synthetic": replace(MAIN, synthetic=200),
    "- dropout": replace(MAIN, dropout=0.0),
    "- prior": replace(MAIN, prior=False),
}
BEGIN, END = "<!-- BEGIN ldh-experiment -->", "<!-- END ldh-experiment -->"


def _uptime() -> str:
    try:
        return subprocess.run(["uptime"], capture_output=True, text=True, check=False).stdout.strip()
    except OSError:
        return "unknown"


def run_experiment(bench: Benchmark, out: Path, seeds: list[int], doc: Path | None) -> dict:
    start = time.time()
    out.mkdir(parents=True, exist_ok=True)
    contexts = MazeContexts(bench)
    val_set = load_split(bench, "val_seen", Variant.PREFIX)
    val_base = summarize(
        "val_seen", "prefix", len(val_set), evaluate(bench, "val_seen", val_set, BASELINES, contexts=contexts)
    )
    ablation = {}
    for name, cfg in ABLATIONS.items():
        tds = []
        for seed in seeds:
            folder = out / "runs" / f"{name.replace('+ ', 'with-').replace('- ', 'no-')}-s{seed}"
            tds.append(train(bench, replace(cfg, seed=seed), folder, contexts=contexts)["best"]["val_td"])
            if name == "learned":
                (out / f"learned-s{seed}.path").write_text(str(folder / "best.pt"))
        ablation[name] = tds
    train_s = time.time() - start

    test_set = load_split(bench, "test", Variant.PREFIX)
    results = evaluate(bench, "test", test_set, BASELINES, contexts=contexts)
    per_seed = {}
    for seed in seeds:
        localizer = load_localizer((out / f"learned-s{seed}.path").read_text())
        seed_results = evaluate(bench, "test", test_set, {"learned": localizer}, seed=seed, contexts=contexts)
        per_seed[seed] = summarize_agent(seed_results)
        results += seed_results
    test = summarize("test", "prefix", len(test_set), results)
    write_csv(out / "test_per_instance.csv", results)
    tests = [c.to_dict() for c in paired_tests(results, [("learned", "center"), ("learned", "colours")])]
    meta = {
        "cut_rule": CUT_RULE,
        "seeds": seeds,
        "val_seen_baselines": val_base,
        "val_seen_ablation": ablation,
        "test": test,
        "test_per_seed": per_seed,
        "paired_tests": tests,
        "timing": {"train_s": train_s, "total_s": time.time() - start},
        "uptime": _uptime(),
    }
    (out / "results.json").write_text(json.dumps(meta, indent=1))
    plot = _plot(results, (doc.parent if doc else out) / "img" / "ldh_test_td.png")
    if doc is not None:
        _write_doc(doc, meta, plot.relative_to(doc.parent))
    return meta


def _plot(results, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path.parent.mkdir(parents=True, exist_ok=True)
    fig, (hist, cdf) = plt.subplots(1, 2, figsize=(10, 3.6))
    top = max(r.td for r in results)
    for agent, per in per_instance(results, "td").items():  # seeds averaged
        td = np.sort(list(per.values()))
        hist.hist(td, bins=np.arange(0, top + 0.25, 0.25), histtype="step", label=agent, linewidth=1.5)
        cdf.step(td, np.arange(1, td.size + 1) / td.size, where="post", label=agent)
    cdf.axvline(HUMANS_TD_M, color="grey", linestyle=":", label=f"humans, mean ({HUMANS_TD_M} m)")
    hist.set_xlabel("TD per test instance (m; learned: mean of seeds)")
    hist.set_ylabel("instances")
    cdf.set_xlabel("TD (m)")
    cdf.set_ylabel("share of test instances with TD <= x")
    cdf.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _write_doc(doc: Path, meta: dict, plot: Path) -> None:
    test = meta["test"]
    lines = [
        BEGIN,
        "",
        f"Test ({test['n']} trials, variant `prefix`, rule `{meta['cut_rule']}`), run once; "
        f"`learned` is the mean of seeds {', '.join(map(str, meta['seeds']))} per instance.",
        "",
        "| agent | TD (m) | Euclid (m) | acc@0.25 | acc@0.5 | acc@1.0 |",
        "|---|---|---|---|---|---|",
    ]
    per_seed = ((f"learned seed {seed}", s) for seed, s in meta["test_per_seed"].items())
    for name, s in [*test["agents"].items(), *per_seed]:
        lines.append(
            f"| {name} | {s['td_mean']:.3f} ± {s['td_std']:.3f} | {s['euclid_mean']:.3f} | "
            f"{s['acc_0.25']:.3f} | {s['acc_0.5']:.3f} | {s['acc_1.0']:.3f} |"
        )
    lines += [
        f"| humans (paper) | {HUMANS_TD_M} | | | | |",
        "",
        "Paired t-tests on per-instance TD, Benjamini-Yekutieli over the family:",
        "",
        "| a | b | n | TD a | TD b | t | p | p (BY) | significant |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for c in meta["paired_tests"]:
        lines.append(
            f"| {c['a']} | {c['b']} | {c['n']} | {c['mean_a']:.3f} | {c['mean_b']:.3f} | {c['t']:.2f} | "
            f"{c['p']:.4f} | {c['p_adjusted']:.4f} | {'yes' if c['significant'] else 'no'} |"
        )
    lines += [
        "",
        "val_seen TD of each configuration (best epoch per seed; development only):",
        "",
        "| configuration | " + " | ".join(f"seed {s}" for s in meta["seeds"]) + " | mean |",
        "|---|" + "---|" * (len(meta["seeds"]) + 1),
    ]
    for name, tds in meta["val_seen_ablation"].items():
        lines.append(f"| {name} | " + " | ".join(f"{t:.3f}" for t in tds) + f" | {np.mean(tds):.3f} |")
    for name, s in meta["val_seen_baselines"]["agents"].items():
        lines.append(f"| {name} (baseline) | " + " | ".join("" for _ in meta["seeds"]) + f" | {s['td_mean']:.3f} |")
    lines += [
        "",
        f"![TD distributions on test]({plot.as_posix()})",
        "",
        f"Wall time {meta['timing']['total_s'] / 60:.1f} min (training {meta['timing']['train_s'] / 60:.1f} min); "
        f"`uptime` at the end: `{meta['uptime']}` (the 2-core machine is shared).",
        "",
        END,
    ]
    text = doc.read_text() if doc.exists() else ""
    block = "\n".join(lines)
    if BEGIN in text and END in text:
        text = text[: text.index(BEGIN)] + block + text[text.index(END) + len(END) :]
    else:
        text = text.rstrip() + "\n\n## Results (`robotslang experiment ldh`)\n\n" + block + "\n"
    doc.write_text(text)

"""`robotslang report ndh DIR`: the paper's two result tables and plots from an experiment.

Reads what `experiment ndh` wrote (results/{val_seen,test}.csv, runs/*/history.json) and
writes DIR/report.md (TD/OTD and SR/SPL tables with significance marks, the tests behind
them, each seed's figures and the tests over per-seed means), DIR/significance.json,
DIR/significance_seeds.json, DIR/td_distribution.png and DIR/learning_curves.png.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from models.stats import Comparison, paired_tests, per_seed, seed_tests
from sim.core.metrics import EpisodeResult, group_by, read_csv, summarize_agent
from sim.core.stepper import MAX_EPISODE_ACTIONS
from sim.tasks.benchmark import EVAL_SPLITS

FEEDBACK_LABEL = {"teacher": "Teacher forcing", "student": "Student forcing"}
BLIND_LABEL = {"none": "vision + language", "vision": "vision-blind", "language": "language-blind"}
BASELINE_LABEL = {"random": "Random", "stop": "Immediate Stop"}
TABLE_METRICS = {"TD/OTD": (("td", "TD"), ("otd", "OTD")), "SR/SPL": (("success", "SR"), ("spl", "SPL"))}
ABLATION_MARK, FEEDBACK_MARK, VARIANT_MARK = "*", "†", "‡"
REFERENCE_MODEL = "baseline"  # the paper's model, which every other variant is tested against


def configurations(agents: set[str]) -> list[tuple[str, str, str]]:
    """(model, feedback, blind) of the learned agents present, in table order."""
    out = []
    models = sorted({a.split("/")[0] for a in agents if a.count("/") == 2})
    for m in models:
        for f in FEEDBACK_LABEL:
            for b in BLIND_LABEL:
                if f"{m}/{f}/{b}" in agents:
                    out.append((m, f, b))
    return out


def comparison_pairs(configs: list[tuple[str, str, str]]) -> list[tuple[str, str]]:
    """Full model vs each ablation (same feedback), student vs teacher (same inputs), and each
    variant's full model vs the baseline's (same feedback)."""
    present = {"/".join(c) for c in configs}
    pairs = []
    for m, f, b in configs:
        if b != "none" and f"{m}/{f}/none" in present:
            pairs.append((f"{m}/{f}/none", f"{m}/{f}/{b}"))
    for m, f, b in configs:
        if f == "student" and f"{m}/teacher/{b}" in present:
            pairs.append((f"{m}/student/{b}", f"{m}/teacher/{b}"))
    for m, f, b in configs:
        if m != REFERENCE_MODEL and b == "none" and f"{REFERENCE_MODEL}/{f}/none" in present:
            pairs.append((f"{m}/{f}/none", f"{REFERENCE_MODEL}/{f}/none"))
    return pairs


def significance(results: dict[str, list[EpisodeResult]], pairs) -> dict[str, list[Comparison]]:
    """Per split: tests on every table metric, BY-corrected within each (split, metric)."""
    return {
        split: [c for metric in ("td", "otd", "success", "spl") for c in paired_tests(rs, pairs, metrics=(metric,))]
        for split, rs in results.items()
    }


def seed_significance(results: dict[str, list[EpisodeResult]], pairs) -> dict[str, list[Comparison]]:
    """Per split: tests over per-seed means, for the pairs with at least two seeds in common."""
    out = {}
    for split, rs in results.items():
        seeds = {agent: set(by_seed) for agent, by_seed in per_seed(rs, "td").items()}
        usable = [(a, b) for a, b in pairs if len(seeds.get(a, set()) & seeds.get(b, set())) >= 2]
        out[split] = (
            [c for metric in ("td", "otd", "success", "spl") for c in seed_tests(rs, usable, metrics=(metric,))]
            if usable
            else []
        )
    return out


def seeds_markdown(results: dict[str, list[EpisodeResult]]) -> str:
    """Each learned configuration's TD / SR / SPL / steps per seed (mean over instances)."""
    lines = ["| split | Driver | seed | TD | SR | SPL | steps | ended by stop |", "|---|---|---|---|---|---|---|---|"]
    for split, rs in results.items():
        for m, f, b in configurations({r.agent for r in rs}):
            agent = f"{m}/{f}/{b}"
            for seed in sorted({r.seed for r in rs if r.agent == agent}):
                mine = [r for r in rs if r.agent == agent and r.seed == seed]
                s = summarize_agent(mine)
                stopped = np.mean([r.steps < MAX_EPISODE_ACTIONS for r in mine])
                lines.append(
                    f"| {split} | {agent} | {seed} | {s['td_mean']:.2f} | {s['sr']:.3f} | {s['spl']:.3f} | "
                    f"{s['steps_mean']:.1f} | {stopped:.2f} |"
                )
    return "\n".join(lines)


def _marks(agent: str, metric: str, tests: list[Comparison]) -> str:
    marks = ""
    for c in tests:
        if c.metric != metric or not c.significant:
            continue
        if c.a.split("/")[0] != c.b.split("/")[0]:  # variant vs baseline: marked on the variant row
            marks += VARIANT_MARK if agent == c.a else ""
        elif c.a.split("/")[1] != c.b.split("/")[1]:  # student vs teacher: marked on the student row
            marks += FEEDBACK_MARK if agent == c.a else ""
        elif agent == c.b:  # full vs ablation: marked on the ablation row
            marks += ABLATION_MARK
    return marks


def _cell(summary: Mapping[str, object], metric: str, marks: str) -> str:
    if metric == "success":
        return f"{summary['sr']:.3f}{marks}"
    if metric == "spl":
        return f"{summary['spl']:.3f}{marks}"
    return f"{summary[metric + '_mean']:.2f} ± {summary[metric + '_std']:.2f}{marks}"


def tables_markdown(results: dict[str, list[EpisodeResult]], tests: dict[str, list[Comparison]]) -> str:
    by_agent = {split: group_by(rs, lambda r: r.agent) for split, rs in results.items()}
    agents = set().union(*(set(a) for a in by_agent.values()))
    rows = [(BASELINE_LABEL[a], a) for a in BASELINE_LABEL if a in agents]
    rows += [(f"{m}: {FEEDBACK_LABEL[f]}, {BLIND_LABEL[b]}", f"{m}/{f}/{b}") for m, f, b in configurations(agents)]
    lines = []
    for title, metrics in TABLE_METRICS.items():
        header = ["Driver"] + [f"{name} ({split})" for split in results for _, name in metrics]
        lines += [f"### {title}", "", "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        for label, agent in rows:
            cells = [label]
            for split in results:
                summary = summarize_agent(by_agent[split][agent]) if agent in by_agent[split] else None
                for metric, _ in metrics:
                    cells.append(
                        _cell(summary, metric, _marks(agent, metric, tests.get(split, []))) if summary else "–"
                    )
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def tests_markdown(tests: dict[str, list[Comparison]]) -> str:
    lines = [
        "| split | metric | A | B | n | mean A | mean B | t | p | p (BY) | significant |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    if not any(tests.values()):
        return "(none: no pair of configurations has two seeds in common)"
    for split, cs in tests.items():
        for c in cs:
            lines.append(
                f"| {split} | {c.metric} | {c.a} | {c.b} | {c.n} | {c.mean_a:.3f} | {c.mean_b:.3f} | "
                f"{c.t:.2f} | {c.p:.3g} | {c.p_adjusted:.3g} | {'yes' if c.significant else 'no'} |"
            )
    return "\n".join(lines)


def plot_td_distributions(results: dict[str, list[EpisodeResult]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(results), figsize=(7 * len(results), 6), squeeze=False)
    for ax, (split, rs) in zip(axes[0], results.items()):
        agents = [a for a in BASELINE_LABEL if any(r.agent == a for r in rs)]
        agents += ["/".join(c) for c in configurations({r.agent for r in rs})]
        data = []
        for a in agents:
            per = group_by((r for r in rs if r.agent == a and np.isfinite(r.td)), lambda r: r.inst_idx)
            data.append([float(np.mean([r.td for r in v])) for v in per.values()])
        ax.boxplot(data, orientation="horizontal", showmeans=True)
        ax.set_yticks(range(1, len(agents) + 1), agents, fontsize=8)
        ax.set_xlabel("topological distance to goal (m), mean over seeds per instance")
        ax.set_title(f"TD distribution, {split}")
        ax.invert_yaxis()
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def plot_learning_curves(out: Path, path: Path) -> bool:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import MaxNLocator

    curves: dict[str, dict[str, list]] = {}
    for hist in sorted((out / "runs").glob("*/*/seed*/val/history.json")):
        model, config = hist.parts[-5], hist.parts[-4]
        curves.setdefault(model, {}).setdefault(config, []).append(json.loads(hist.read_text()))
    if not curves:
        return False
    fig, axes = plt.subplots(1, len(curves), figsize=(7 * len(curves), 5), squeeze=False)
    for ax, (model, configs) in zip(axes[0], sorted(curves.items())):
        for config, runs in sorted(configs.items()):
            iters = [e["iteration"] for e in runs[0] if "val_td" in e]
            tds = np.array(
                [
                    [e["val_td"] for e in run if "val_td" in e][: len(iters)]
                    for run in runs
                    if len([e for e in run if "val_td" in e]) >= len(iters)
                ]
            )
            ax.plot(
                iters, tds.mean(axis=0), marker="o", label=f"{config} ({len(tds)} seed{'' if len(tds) == 1 else 's'})"
            )
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # iterations are whole: no 1.5
        ax.set_xlabel("training iteration (batch of 100)")
        ax.set_ylabel("val_seen TD (m), mean over seeds")
        ax.set_title(f"learning curves: {model}")
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return True


def write_report(out: str | Path) -> Path:
    out = Path(out)
    results = {
        str(s): read_csv(out / "results" / f"{s}.csv") for s in EVAL_SPLITS if (out / "results" / f"{s}.csv").exists()
    }
    if not results:
        raise FileNotFoundError(f"{out}/results: no val_seen.csv or test.csv; run `robotslang experiment ndh` first")
    agents = set().union(*({r.agent for r in rs} for rs in results.values()))
    pairs = comparison_pairs(configurations(agents))
    tests = significance(results, pairs)
    across_seeds = seed_significance(results, pairs)
    for name, family in (("significance.json", tests), ("significance_seeds.json", across_seeds)):
        (out / name).write_text(json.dumps({s: [c.to_dict() for c in cs] for s, cs in family.items()}, indent=2))
    plot_td_distributions(results, out / "td_distribution.png")
    has_curves = plot_learning_curves(out, out / "learning_curves.png")
    meta_path = out / "experiment.json"
    meta = json.loads(meta_path.read_text()) if meta_path.exists() else {}
    lines = ["# NDH results", ""]
    if meta:
        lines += [
            f"Models {', '.join(meta.get('models', []))}; seeds {meta.get('seeds')}; "
            f"{meta.get('iters')} training iterations per run (validation every {meta.get('eval_every')}); "
            f"wall time {meta.get('timing', {}).get('total_s', float('nan')) / 60:.1f} min.",
            "",
        ]
    lines += [
        tables_markdown(results, tests),
        f"{ABLATION_MARK}: significantly different from the full model with the same feedback; "
        f"{FEEDBACK_MARK}: student forcing significantly different from teacher forcing with the same "
        f"inputs; {VARIANT_MARK}: full model significantly different from the {REFERENCE_MODEL}'s with "
        "the same feedback (paired t-tests over instances, metrics averaged over seeds per instance, "
        "Benjamini-Yekutieli within each split and metric, alpha 0.05).",
        "",
        "## Tests",
        "",
        tests_markdown(tests),
        "",
        "## Each seed",
        "",
        f"Each training seed's figures (mean over instances; a cap-ended episode ran {MAX_EPISODE_ACTIONS} moves):",
        "",
        seeds_markdown(results),
        "",
        "## Tests across seeds",
        "",
        "The same pairs, each seed's mean over instances as one observation (paired t-tests over seeds, "
        "Benjamini-Yekutieli within each split and metric, alpha 0.05): a difference significant here "
        "holds across training runs, not only across the instances of these runs.",
        "",
        tests_markdown(across_seeds),
        "",
        "![TD distributions](td_distribution.png)",
        "",
    ]
    if has_curves:
        lines += ["![learning curves](learning_curves.png)", ""]
    path = out / "report.md"
    path.write_text("\n".join(lines))
    return path

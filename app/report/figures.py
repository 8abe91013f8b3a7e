"""The dataset section's figures (PNG, matplotlib's Agg: no display needed)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after choosing the backend)
from matplotlib.figure import Figure  # noqa: E402
from matplotlib.ticker import MaxNLocator  # noqa: E402

from app.report.study import DialogNumbers, TeamScores  # noqa: E402
from app.study.answers import ItemRatings  # noqa: E402


def _save(fig: Figure, out: Path) -> Path:
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def dialog_lengths(dialog: DialogNumbers, out: Path) -> Path:
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.5))
    per = dialog["per_dialog"]
    panels = (
        (axes[0], per["messages"], dialog["messages"]["mean"], "messages per dialog"),
        (axes[1], per["words"], dialog["words"]["mean"], "words per dialog"),
    )
    for ax, values, mean, label in panels:
        # Whole-number bins (at most 20), each centred on the counts it holds.
        low, high = min(values, default=0), max(values, default=0)
        step = max(1, -(-(high - low + 1) // 20))
        ax.hist(values, bins=[b - 0.5 for b in range(low, high + step + 1, step)], color="#4878a8", edgecolor="white")
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))
        if mean is not None:
            ax.axvline(mean, color="#c03030", linestyle="--", label=f"mean {mean:.1f}")
            ax.legend()
        ax.set_xlabel(label)
        ax.set_ylabel("dialogs")
    return _save(fig, out)


def leaderboard(board: dict[str, TeamScores], out: Path) -> Path:
    ranked = [(team, row["best"]) for team, row in board.items() if row["best"] is not None]
    fig, ax = plt.subplots(figsize=(7, 0.5 + 0.45 * max(1, len(ranked))))
    ax.barh([t for t, _ in ranked][::-1], [s for _, s in ranked][::-1], color="#4878a8")
    ax.set_xlabel("best score (s: time + penalty per move; lower is better)")
    ax.set_title("Leaderboard")
    return _save(fig, out)


def learning_curves(board: dict[str, TeamScores], out: Path) -> Path:
    fig, ax = plt.subplots(figsize=(7, 4))
    for team, row in board.items():
        if row["scores"]:
            ax.plot(range(1, len(row["scores"]) + 1), row["scores"], marker="o", label=team)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("trial number (the team's own order)")
    ax.set_ylabel("score (s)")
    ax.set_title("Learning curves")
    if board:
        ax.legend(fontsize="small")
    return _save(fig, out)


def questionnaire(items: dict[str, ItemRatings], out: Path) -> Path:
    """Each rating item's answers by seat: how many gave each rating (grouped bars per seat)."""
    fig, axes = plt.subplots(1, max(1, len(items)), figsize=(4.5 * max(1, len(items)), 3.5), squeeze=False)
    for ax, (item_id, item) in zip(axes[0], items.items(), strict=False):
        seats = item["by_seat"]
        ratings = [int(r) for r in next(iter(seats.values()))["counts"]]
        width = 0.8 / len(seats)
        for k, (seat, row) in enumerate(seats.items()):
            offsets = [r - 0.4 + width * (k + 0.5) for r in ratings]
            ax.bar(offsets, list(row["counts"].values()), width, label=f"{seat} (n={row['n']})")
        ax.set_xticks(ratings)
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_xlabel("rating")
        ax.set_ylabel("answers")
        ax.set_title(item_id)
        ax.legend(fontsize="small")
    if not items:
        axes[0][0].set_axis_off()
        axes[0][0].text(0.5, 0.5, "no rating items answered", ha="center", va="center")
    return _save(fig, out)

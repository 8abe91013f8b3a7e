"""The dataset section as Markdown, from the numbers `study_numbers`/`benchmark_numbers` give."""

from __future__ import annotations

from app.annotation.events import TITLES
from app.report.benchmark import BenchmarkNumbers
from app.report.study import StudyNumbers


def _f(value: float | None, digits: int = 1) -> str:
    return "n/a" if value is None else f"{value:.{digits}f}"


def study_markdown(n: StudyNumbers, figures: dict[str, str]) -> str:
    c, d = n["counts"], n["dialog"]
    lines = [
        f"# Dataset: study {n['study']}",
        "",
        f"{c['trials']} trials on {c['layouts']} layouts ({c['mazes']} mazes), played by {c['participants']} "
        f"participants in {c['teams']} teams.",
        "",
        "| team | trials |",
        "| --- | --- |",
        *(f"| {team} | {k} |" for team, k in c["trials_per_team"].items()),
        "",
        "## Dialogs",
        "",
        f"{_f(n['messages_per_dialog'])} messages and {_f(n['words_per_dialog'])} words per dialog on average "
        f"(messages: median {_f(d['messages']['median'])}, {_f(d['messages']['min'], 0)} to "
        f"{_f(d['messages']['max'], 0)}; words: median {_f(d['words']['median'])}).",
        "",
        "| role | messages per dialog | words per dialog |",
        "| --- | --- | --- |",
        *(
            f"| {role} | {_f(r['messages_per_dialog'])} | {_f(r['words_per_dialog'])} |"
            for role, r in d["per_role"].items()
        ),
        "",
        f"![dialog lengths]({figures['dialog_lengths']})",
        "",
        f"Trials took {_f(n['duration_minutes']['mean'])} minutes on average (start to the last target) "
        f"and {_f(n['moves']['mean'])} moves (executed; {_f(n['refused_moves']['mean'])} move requests refused "
        "besides, not counted).",
        "",
        "## Folds (split by layout: no layout in two folds)",
        "",
        "| fold | layouts | trials | NDH instances | LDH instances |",
        "| --- | --- | --- | --- | --- |",
        *(
            f"| {fold} | {f['layouts']} | {f['trials']} | {f['ndh_instances']} | {f['ldh_instances']} |"
            for fold, f in n["folds"].items()
        ),
        "",
        "| fold | layout | trials | NDH instances | LDH instances |",
        "| --- | --- | --- | --- | --- |",
        *(
            f"| {fold} | {layout} | {r['trials']} | {r['ndh_instances']} | {r['ldh_instances']} |"
            for fold, f in n["folds"].items()
            for layout, r in sorted(f["by_layout"].items())
        ),
        "",
        "## Phenomena",
        "",
        f"Over {n['phenomena']['annotated_dialogs']} annotated dialogs.",
        "",
        "| phenomenon | dialogs | frequency | example |",
        "| --- | --- | --- | --- |",
    ]
    for tag, row in n["phenomena"]["tags"].items():
        ex = row["example"]
        example = f"trial {ex['trial']}, message {ex['message']} ({ex['role']}): “{ex['text']}”" if ex else ""
        freq = "n/a" if row["frequency"] is None else f"{100 * row['frequency']:.1f} %"
        lines.append(f"| {TITLES.get(tag, tag)} | {row['dialogs']} | {freq} | {example} |")
    a = n["agreement"]
    lines += [
        "",
        "## Agreement",
        "",
        f"{a['double_annotated_trials']} dialogs annotated twice; localization cuts "
        f"{_f(a['cut_distance']['mean'], 2)} messages apart on average.",
        "",
        "| phenomenon | Cohen's kappa |",
        "| --- | --- |",
        *(f"| {TITLES.get(t, t)} | {_f(k, 3)} |" for t, k in a["kappa"].items()),
        "",
        "## Leaderboard and learning curves",
        "",
        f"![leaderboard]({figures['leaderboard']})",
        "",
        f"![learning curves]({figures['learning_curves']})",
        "",
        "## Questionnaires",
        "",
        f"{n['questionnaire']['answers']} questionnaires answered after trials (ratings 1-5, by the seat held).",
        "",
        "| item | seat | answers | mean | 1 | 2 | 3 | 4 | 5 |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
        *(
            f"| {item['prompt']} | {seat} | {row['n']} | {_f(row['mean'], 2)} | "
            + " | ".join(str(k) for k in row["counts"].values())
            + " |"
            for item in n["questionnaire"]["items"].values()
            for seat, row in item["by_seat"].items()
        ),
        "",
        f"![questionnaire ratings]({figures['questionnaire']})",
        "",
    ]
    return "\n".join(lines)


def benchmark_markdown(n: BenchmarkNumbers) -> str:
    paper = n["paper"]
    lines = [
        f"# Dataset: the public benchmark ({n['source']})",
        "",
        "| figure | these files | the paper |",
        "| --- | --- | --- |",
        f"| dialogs (trials) | {n['counts']['trials']} | |",
        f"| layouts | {n['counts']['layouts']} | |",
        f"| messages per dialog | {_f(n['messages_per_dialog'])} | {paper['messages_per_dialog']} |",
        f"| words per dialog | {_f(n['words_per_dialog'])} | {paper['words_per_dialog']} |",
        "",
        "| split | instances | runs | layouts | layouts in another split |",
        "| --- | --- | --- | --- | --- |",
        *(
            f"| {f['split']} | {f['instances']} | {f['runs']} | {f['layouts']} | {f['shared_layouts']} |"
            for f in n["folds"]
        ),
        "",
        "Not computable from the benchmark's files:",
        "",
        *(f"- {key}: {why}" for key, why in n["not_in_files"].items()),
        "",
    ]
    return "\n".join(lines)

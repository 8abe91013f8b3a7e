"""Every number of a study's dataset section, from its trials' event logs and annotations.

Folds are the study's split by layout (`app.export.folds`), as the paper split its data, so that no
two folds share a physical layout.
"""

from __future__ import annotations

import statistics
from collections import Counter, defaultdict
from collections.abc import Mapping, Sequence
from typing import TypedDict

from sqlalchemy.orm import Session, sessionmaker

from app.annotation.agreement import AgreementNumbers
from app.annotation.dialog import messages
from app.annotation.events import Phenomenon
from app.annotation.log import AnnotationLog
from app.annotation.study import study_agreement
from app.db.models import Team, Trial
from app.export.folds import SavedFolds
from app.export.ndh import ldh_instances, ndh_instances
from app.export.record import TrialRecord
from app.export.source import exported_trial_ids, load_trial
from app.mazes import Mazes
from app.settings import Settings
from app.study.answers import ItemRatings, asked, items, rating_distributions, study_answers
from app.study.config import StudyFiles
from sim.tasks.benchmark import Split
from sim.trial.state import TrialState, fold


class Distribution(TypedDict):
    mean: float | None
    median: float | None
    min: float | None
    max: float | None


class RoleNumbers(TypedDict):
    messages_per_dialog: float
    words_per_dialog: float


class PerDialog(TypedDict):
    messages: list[int]
    words: list[int]


class DialogNumbers(TypedDict):
    messages_per_dialog: float | None
    words_per_dialog: float | None
    messages: Distribution
    words: Distribution
    per_dialog: PerDialog
    per_role: dict[str, RoleNumbers]


class StudyCounts(TypedDict):
    trials: int
    layouts: int
    mazes: int
    participants: int
    teams: int
    trials_per_team: dict[str, int]


class TrialNumbers(TypedDict):
    moves: int
    refused_moves: int
    score: float | None


class LayoutRow(TypedDict):
    trials: int
    ndh_instances: int
    ldh_instances: int


class FoldRow(LayoutRow):
    layouts: int
    by_layout: dict[str, LayoutRow]


class Example(TypedDict):
    trial: int
    message: int
    role: str
    text: str


class PhenomenonRow(TypedDict):
    dialogs: int
    frequency: float | None  # share of the annotated dialogs
    example: Example | None


class PhenomenaTable(TypedDict):
    annotated_dialogs: int
    tags: dict[str, PhenomenonRow]


class TeamScores(TypedDict):
    scores: list[float]  # in the order the team played its trials
    best: float | None
    mean: float | None


class QuestionnaireNumbers(TypedDict):
    answers: int
    items: dict[str, ItemRatings]


class StudyNumbers(TypedDict):
    """study.json of `report study`: every number of the study's dataset section."""

    study: str
    counts: StudyCounts
    messages_per_dialog: float | None
    words_per_dialog: float | None
    dialog: DialogNumbers
    duration_minutes: Distribution
    moves: Distribution
    refused_moves: Distribution
    move_penalty_s: float
    trials: dict[str, TrialNumbers]
    folds: dict[str, FoldRow]
    phenomena: PhenomenaTable
    agreement: AgreementNumbers
    leaderboard: dict[str, TeamScores]
    questionnaire: QuestionnaireNumbers


def distribution(values: Sequence[float]) -> Distribution:
    if not values:
        return {"mean": None, "median": None, "min": None, "max": None}
    return {
        "mean": statistics.fmean(values),
        "median": float(statistics.median(values)),
        "min": float(min(values)),
        "max": float(max(values)),
    }


def words(text: str) -> int:
    return len(text.split())


def dialog_numbers(dialogs: Sequence[Sequence[tuple[str, str]]]) -> DialogNumbers:
    """Messages and words per dialog ((role, text) turns), overall and per role."""
    roles = sorted({role for d in dialogs for role, _ in d})
    msgs = [len(d) for d in dialogs]
    wrds = [sum(words(t) for _, t in d) for d in dialogs]
    return {
        "messages_per_dialog": statistics.fmean(msgs) if msgs else None,
        "words_per_dialog": statistics.fmean(wrds) if wrds else None,
        "messages": distribution(msgs),
        "words": distribution(wrds),
        "per_dialog": {"messages": msgs, "words": wrds},
        "per_role": {
            role: {
                "messages_per_dialog": statistics.fmean([sum(r == role for r, _ in d) for d in dialogs]),
                "words_per_dialog": statistics.fmean([sum(words(t) for r, t in d if r == role) for d in dialogs]),
            }
            for role in roles
        },
    }


def study_numbers(sessions: sessionmaker[Session], settings: Settings, mazes: Mazes, study: str) -> StudyNumbers:
    with sessions() as db:
        ids = exported_trial_ids(db, study=study)
        records = [load_trial(db, settings, i) for i in ids]
        trials = {t.id: t for t in (db.get(Trial, i) for i in ids) if t is not None}
        layout_of = mazes.layouts()
        teams: dict[str, list[int]] = defaultdict(list)
        participants: set[int] = set()
        for trial_id in ids:
            trial = trials[trial_id]
            team = db.get(Team, trial.team_id)
            teams[team.name if team else str(trial.team_id)].append(trial_id)
            if team is not None:
                participants |= {team.member_a_id, team.member_b_id}
            participants |= {p for p in (trial.commander_id, trial.driver_id) if p is not None}
        dialogs = [[(m.role, m.text) for m in messages(r.events)] for r in records]
        # Moves and scores by the trial's own fold, as the leaderboard counts them: executed moves
        # only; refused requests apart.
        states = {int(r.trial_id): fold(r.events) for r in records}
        files = StudyFiles.of(settings.data_dir)
        penalty = files.move_penalty_s(study, settings.move_penalty_s)
        durations = [trials[int(r.trial_id)].active_s or 0.0 for r in records]
        answers = study_answers(db, study)
        dialog = dialog_numbers(dialogs)
        return {
            "study": study,
            "counts": {
                "trials": len(ids),
                "layouts": len({layout_of.get(r.maze, r.maze) for r in records}),
                "mazes": len({r.maze for r in records}),
                "participants": len(participants),
                "teams": len(teams),
                "trials_per_team": {name: len(t) for name, t in sorted(teams.items())},
            },
            "messages_per_dialog": dialog["messages_per_dialog"],
            "words_per_dialog": dialog["words_per_dialog"],
            "dialog": dialog,
            "duration_minutes": distribution([d / 60 for d in durations]),
            "moves": distribution([float(state.moves) for state in states.values()]),
            "refused_moves": distribution([float(state.refused) for state in states.values()]),
            "move_penalty_s": penalty,
            "trials": {
                str(i): {"moves": state.moves, "refused_moves": state.refused, "score": state.score(penalty)}
                for i, state in states.items()
            },
            "folds": fold_table(records, mazes, layout_of, SavedFolds.of(settings.data_dir, study)),
            "phenomena": phenomena_table(records),
            "agreement": study_agreement(db, AnnotationLog(sessions), study),
            "leaderboard": leaderboard(teams, states, penalty),
            "questionnaire": {
                "answers": len(answers),
                "items": rating_distributions(answers, items(asked(files, study, answers)) if answers else []),
            },
        }


def fold_table(
    records: Sequence[TrialRecord], mazes: Mazes, layout_of: Mapping[str, str], saved: SavedFolds
) -> dict[str, FoldRow]:
    """Per fold: layouts, trials, NDH and LDH instances, and the same per layout; the folds are the
    study's saved split (`export --folds`), or the default one it would draw."""
    layout = {r.trial_id: layout_of.get(r.maze, r.maze) for r in records}
    folds = saved.preview(layout.values())
    table: dict[str, FoldRow] = {
        str(s): {"layouts": 0, "trials": 0, "ndh_instances": 0, "ldh_instances": 0, "by_layout": {}} for s in Split
    }
    for r in records:
        fold = table[folds[layout[r.trial_id]]]
        maze = mazes.load(r.maze)
        row = fold["by_layout"].setdefault(layout[r.trial_id], {"trials": 0, "ndh_instances": 0, "ldh_instances": 0})
        ndh, ldh = len(ndh_instances(r, maze)), len(ldh_instances(r, maze))
        for counted in (row, fold):
            counted["trials"] += 1
            counted["ndh_instances"] += ndh
            counted["ldh_instances"] += ldh
    for fold in table.values():
        fold["layouts"] = len(fold["by_layout"])
    return table


def phenomena_table(records: Sequence[TrialRecord]) -> PhenomenaTable:
    """Share of the annotated dialogs (those with a resolved cut or tag) showing each phenomenon,
    and an example: the first message anchored to it."""
    annotated = [r for r in records if r.tags or r.localized_after is not None]
    found = Counter(tag for r in annotated for tag in r.tags)
    tags = [str(p) for p in Phenomenon] + sorted(set(found) - {str(p) for p in Phenomenon})
    table: dict[str, PhenomenonRow] = {}
    for tag in tags:
        example: Example | None = None
        for r in annotated:
            if tag in r.tags:
                said = {m.number: m for m in messages(r.events)}
                m = said.get(r.tags[tag][0])
                if m is not None:
                    example = {"trial": int(r.trial_id), "message": m.number, "role": m.role, "text": m.text}
                    break
        table[tag] = {
            "dialogs": found[tag],
            "frequency": found[tag] / len(annotated) if annotated else None,
            "example": example,
        }
    return {"annotated_dialogs": len(annotated), "tags": table}


def leaderboard(
    teams: Mapping[str, Sequence[int]], states: Mapping[int, TrialState], penalty: float
) -> dict[str, TeamScores]:
    """Each team's scores in the order it played its trials (its learning curve), best and mean."""
    out: dict[str, TeamScores] = {}
    for name, ids in teams.items():
        scores = [score for i in sorted(ids) if (score := states[i].score(penalty)) is not None]
        out[name] = {
            "scores": scores,
            "best": min(scores) if scores else None,
            "mean": statistics.fmean(scores) if scores else None,
        }
    return dict(sorted(out.items(), key=lambda kv: (kv[1]["best"] is None, kv[1]["best"] or 0.0)))

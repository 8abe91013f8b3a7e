"""LDH human studies: participants read a dialog, look at the Commander's map and mark where the
robot is; the server scores each mark by TD on the benchmark's graph (`sim.tasks.ldh_eval`).

A study's instances are frozen in the database when it is created, from a folder in the
benchmark's layout (the public benchmark, variant prefix or full, or a folder the platform's
own `robotslang export --format ndh` wrote, whose `LDH-data` holds exact instances). Every
answer is an event of the study's log, committed before the participant is told it was taken,
stamped by the server's one clock and numbered in order. A participant answers the instances
one at a time, in order, once each; the truth is theirs to see only after the last one.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, fields
from enum import StrEnum
from pathlib import Path
from typing import Any, TypeVar

from sqlalchemy import Select, func, insert, select
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session, sessionmaker

from app.clock import ServerClock
from app.db.models import LDHStudy, LDHStudyEvent, LDHStudyInstance, LDHStudyParticipant
from app.i18n import Language, Text
from app.mazes import commander_map_png
from app.settings import Settings
from sim.core.geometry import TABLE_HEIGHT_M, TABLE_WIDTH_M
from sim.tasks.benchmark import Benchmark, BenchmarkError, Split
from sim.tasks.ldh import LDHInstance, Variant, load_split
from sim.tasks.ldh_eval import ACC_RADII_M, MazeContext, score

Row = TypeVar("Row")
APPEND_ATTEMPTS = 5  # two answers racing for the same seq: the loser takes the next one


class LocalizationStudyError(ValueError):
    """A study that cannot be made or an answer that cannot be taken, with the reason why."""


class EventKind(StrEnum):
    CREATED = "study_created"
    INVITED = "participant_invited"
    ANSWERED = "answer"


@dataclass(frozen=True)
class Answer:
    seq: int
    t_ns: int
    participant_id: int
    position: int
    x: float
    y: float
    heading: float | None
    td: float
    euclid: float

    @classmethod
    def of(cls, event: LDHStudyEvent) -> Answer:
        logged = {f.name: event.payload[f.name] for f in fields(cls)[2:]}  # the payload holds all but seq, t_ns
        return cls(event.seq, event.t_ns, **logged)


class LocalizationStudies:
    """LDH localization studies on the server's database; benchmarks and graphs are loaded once per folder."""

    def __init__(self, settings: Settings, db: sessionmaker[Session], clock: ServerClock) -> None:
        self.settings, self.db, self.clock = settings, db, clock
        self._benchmarks: dict[str, Benchmark] = {}
        self._contexts: dict[tuple[str, str], MazeContext] = {}
        self._maps: dict[tuple[str, str], bytes] = {}
        # A double submit racing itself: the check for an earlier answer and the append go together.
        # (Across server processes the check inside the append's transaction still refuses a later one.)
        self._answering = threading.Lock()

    # -- sources --------------------------------------------------------------------
    def default_source(self) -> str:
        return str(self.settings.benchmark or "")

    def _allowed(self, source: str) -> Path:
        """The benchmark the server is configured with, or a folder under its data directory (an
        export), given whole or relative to the data directory (`export`)."""
        settings = self.settings
        path = Path(source).expanduser()
        path = (path if path.is_absolute() else settings.data_dir / path).resolve()
        roots = [settings.data_dir.resolve()] + ([settings.benchmark.resolve()] if settings.benchmark else [])
        if not any(path == root or root in path.parents for root in roots):
            raise LocalizationStudyError(
                f"{source}: a study draws from the configured benchmark or a folder under "
                f"{settings.data_dir} (an export of this platform's trials)"
            )
        return path

    def benchmark(self, source: str) -> Benchmark:
        if source not in self._benchmarks:
            try:
                self._benchmarks[source] = Benchmark(source, cache_dir=self.settings.cache_dir)
            except BenchmarkError as err:
                raise LocalizationStudyError(str(err)) from None
        return self._benchmarks[source]

    def context(self, source: str, run: str) -> MazeContext:
        if (source, run) not in self._contexts:
            self._contexts[source, run] = MazeContext(run, self.benchmark(source).graph(run, "benchmark"))
        return self._contexts[source, run]

    def map_png(self, source: str, run: str) -> bytes:
        """The Commander's map of a study's maze: walls and the three landmarks, never the truth."""
        if (source, run) not in self._maps:
            self._maps[source, run] = commander_map_png(self.benchmark(source).maze(run))
        return self._maps[source, run]

    # -- the experimenter -------------------------------------------------------------
    def create(
        self,
        experimenter_id: int,
        name: str,
        source: str,
        split: str,
        variant: str,
        limit: int | None = None,
        language: Language = Language.en,
    ) -> int:
        """A new study of the split's instances (the first `limit` of them), its participant's pages
        in `language`; its id."""
        name = name.strip()
        if not name:
            raise LocalizationStudyError("give the study a name")
        if split not in tuple(Split):
            raise LocalizationStudyError(f"unknown split {split!r}; expected one of {', '.join(Split)}")
        try:
            chosen = Variant(variant)
        except ValueError:
            raise LocalizationStudyError(f"unknown variant {variant!r}; expected prefix or full") from None
        source = str(self._allowed(source))
        try:
            instances = load_split(self.benchmark(source), split, chosen)
        except (BenchmarkError, OSError) as err:
            raise LocalizationStudyError(str(err)) from None
        instances = instances[:limit] if limit else instances
        if not instances:
            raise LocalizationStudyError(f"{source}: split {split} has no LDH instances")
        with self.db.begin() as db:
            study = LDHStudy(
                name=name[:80],
                source=source,
                split=split,
                variant=instances[0].variant.value,
                language=language,
                experimenter_id=experimenter_id,
            )
            db.add(study)
            db.flush()
            db.add_all(
                LDHStudyInstance(
                    study_id=study.id,
                    position=k,
                    inst_idx=i.inst_idx,
                    run=i.run,
                    dialog=[list(t) for t in i.dialog],
                    true_x=i.x,
                    true_y=i.y,
                    true_heading=i.heading,
                )
                for k, i in enumerate(instances)
            )
            study_id = study.id
        self._append(study_id, EventKind.CREATED, {"split": split, "variant": study.variant, "n": len(instances)})
        return study_id

    def invite(self, study_id: int, name: str) -> int:
        name = name.strip()
        if not name:
            raise LocalizationStudyError("give the participant a name or a code")
        try:
            with self.db.begin() as db:
                participant = LDHStudyParticipant(study_id=self.study(study_id).id, name=name[:80])
                db.add(participant)
                db.flush()
                participant_id = participant.id
        except IntegrityError:
            raise LocalizationStudyError(f"this study already has a participant called {name!r}") from None
        self._append(study_id, EventKind.INVITED, {"participant_id": participant_id, "name": name[:80]})
        return participant_id

    def _rows(self, query: Select[Row]) -> list[Row]:
        with self.db() as db:
            return list(db.scalars(query))

    def all_studies(self) -> list[LDHStudy]:
        return self._rows(select(LDHStudy).order_by(LDHStudy.id.desc()))

    def study(self, study_id: int) -> LDHStudy:
        with self.db() as db:
            study = db.get(LDHStudy, study_id)
        if study is None:
            raise LookupError(f"LDH study {study_id} does not exist")
        return study

    def instances(self, study_id: int) -> list[LDHStudyInstance]:
        of_study = select(LDHStudyInstance).where(LDHStudyInstance.study_id == study_id)
        return self._rows(of_study.order_by(LDHStudyInstance.position))

    def participants(self, study_id: int) -> list[LDHStudyParticipant]:
        of_study = select(LDHStudyParticipant).where(LDHStudyParticipant.study_id == study_id)
        return self._rows(of_study.order_by(LDHStudyParticipant.id))

    def participant(self, study_id: int, participant_id: int) -> LDHStudyParticipant:
        """The participant a link names, who must belong to the study it names."""
        with self.db() as db:
            p = db.get(LDHStudyParticipant, participant_id)
        if p is None or p.study_id != study_id:
            raise LookupError("this study link names no participant of its study")
        return p

    def answers(self, study_id: int, participant_id: int | None = None) -> list[Answer]:
        with self.db() as db:
            rows = db.scalars(
                select(LDHStudyEvent)
                .where(LDHStudyEvent.study_id == study_id, LDHStudyEvent.kind == EventKind.ANSWERED.value)
                .order_by(LDHStudyEvent.seq)
            )
            answers = [Answer.of(r) for r in rows]
        return [a for a in answers if participant_id is None or a.participant_id == participant_id]

    # -- the participant --------------------------------------------------------------
    def next_position(self, study_id: int, participant_id: int) -> int | None:
        """The instance the participant answers now; None once they have answered all."""
        n = len(self.instances(study_id))
        done = len(self.answers(study_id, participant_id))
        return done if done < n else None

    def answer(
        self, study_id: int, participant_id: int, position: int, x: float, y: float, heading: float | None
    ) -> Answer:
        """Score and record a mark; refused for any instance but the one the participant is on."""
        with self._answering:
            expected = self.next_position(study_id, participant_id)
            if expected is None:
                raise LocalizationStudyError(Text("you have answered every instance of this study"))
            if position != expected:
                raise LocalizationStudyError(
                    Text(
                        "instance {n} is not the one to answer now (that is {expected})",
                        n=position + 1,
                        expected=expected + 1,
                    )
                )
            if not (math.isfinite(x) and math.isfinite(y) and 0 <= x <= TABLE_WIDTH_M and 0 <= y <= TABLE_HEIGHT_M):
                raise LocalizationStudyError(Text("the mark must lie on the map"))
            if heading is not None and not math.isfinite(heading):
                raise LocalizationStudyError(Text("the heading must be a number of radians"))
            study, inst = self.study(study_id), self.instances(study_id)[position]
            truth = LDHInstance(
                inst.inst_idx, inst.run, inst.true_x, inst.true_y, inst.true_heading, (), Variant(study.variant)
            )
            ctx = self.context(study.source, inst.run)
            td, euclid, _ = score(ctx, ctx.one_hot(ctx.node_at(x, y)), truth)
            payload = {
                "participant_id": participant_id,
                "position": position,
                "inst_idx": inst.inst_idx,
                "x": x,
                "y": y,
                "heading": heading,
                "td": td,
                "euclid": euclid,
            }
            seq, t_ns = self._append(
                study_id,
                EventKind.ANSWERED,
                payload,
                unique=lambda db: self._answered(db, study_id, participant_id, position),
            )
            return Answer(seq, t_ns, participant_id, position, x, y, heading, td, euclid)

    @staticmethod
    def _answered(db: Session, study_id: int, participant_id: int, position: int) -> bool:
        """Whether the participant's answer to `position` is already in the log (a double submit)."""
        payloads: Iterable[dict[str, Any]] = db.scalars(
            select(LDHStudyEvent.payload).where(
                LDHStudyEvent.study_id == study_id, LDHStudyEvent.kind == EventKind.ANSWERED.value
            )
        )
        return any(p["participant_id"] == participant_id and p["position"] == position for p in payloads)

    # -- the log ----------------------------------------------------------------------
    def _append(
        self, study_id: int, kind: EventKind, payload: dict[str, Any], unique: Callable[[Session], bool] | None = None
    ) -> tuple[int, int]:
        """Commit one event with the next seq and a stamp never before the last one; (seq, t_ns)."""
        for _ in range(APPEND_ATTEMPTS):
            try:
                with self.db.begin() as db:
                    if unique is not None and unique(db):
                        raise LocalizationStudyError("this instance is answered already")
                    last_seq, last_t = db.execute(
                        select(func.max(LDHStudyEvent.seq), func.max(LDHStudyEvent.t_ns)).where(
                            LDHStudyEvent.study_id == study_id
                        )
                    ).one()
                    seq = (last_seq or 0) + 1
                    t_ns = max(self.clock.now_ns(), (last_t or 0) + 1)
                    db.execute(
                        insert(LDHStudyEvent),
                        {"study_id": study_id, "seq": seq, "kind": kind.value, "t_ns": t_ns, "payload": payload},
                    )
                return seq, t_ns
            except IntegrityError:
                continue
        raise LocalizationStudyError("the study's log is busy; submit again")

    # -- results ----------------------------------------------------------------------
    def results(self, study_id: int) -> dict[str, Any]:
        """Every answer with its truth, and means per participant and per instance (the export's JSON)."""
        study, instances = self.study(study_id), self.instances(study_id)
        names = {p.id: p.name for p in self.participants(study_id)}
        rows = [answer_row(a, names[a.participant_id], instances[a.position]) for a in self.answers(study_id)]
        per_participant = [
            {
                "participant_id": pid,
                "participant": name,
                **_summary([r for r in rows if r["participant"] == name], len(instances)),
            }
            for pid, name in names.items()
        ]
        per_instance = [
            {
                "position": i.position,
                "inst_idx": i.inst_idx,
                "run": i.run,
                **_summary([r for r in rows if r["position"] == i.position], len(names)),
            }
            for i in instances
        ]
        return {
            "study": {
                "id": study.id,
                "name": study.name,
                "split": study.split,
                "variant": study.variant,
                "source": study.source,
                "n_instances": len(instances),
            },
            "answers": rows,
            "per_participant": per_participant,
            "per_instance": per_instance,
        }


CSV_COLUMNS = (
    "seq",
    "t_ns",
    "participant",
    "position",
    "inst_idx",
    "run",
    "x",
    "y",
    "heading",
    "true_x",
    "true_y",
    "true_heading",
    "td",
    "euclid",
)


def answer_row(a: Answer, participant: str, inst: LDHStudyInstance) -> dict[str, Any]:
    row = asdict(a)
    row.pop("participant_id")
    return {
        **row,
        "participant": participant,
        "inst_idx": inst.inst_idx,
        "run": inst.run,
        "true_x": inst.true_x,
        "true_y": inst.true_y,
        "true_heading": inst.true_heading,
    }


def _summary(rows: list[dict[str, Any]], of: int) -> dict[str, Any]:
    """Answers given out of `of`, mean TD and Euclidean error, and accuracy per radius (None with none)."""
    n = len(rows)
    out: dict[str, Any] = {
        "answered": n,
        "of": of,
        "td_mean": sum(r["td"] for r in rows) / n if n else None,
        "euclid_mean": sum(r["euclid"] for r in rows) / n if n else None,
    }
    for radius in ACC_RADII_M:
        out[f"acc_{radius}"] = sum(r["td"] <= radius for r in rows) / n if n else None
    return out

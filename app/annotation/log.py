"""`AnnotationLog`: the annotation events of every trial, in table `annotation_event`, and what
they add up to. Nothing is overwritten: a revision is a new event naming the one it replaces."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

from sqlalchemy import select
from sqlalchemy.orm import Session, sessionmaker

from app.annotation.events import Adjudicated, AnnotationEventModel, CutMarked, Submitted, Tagged, parse
from app.db.models import AnnotationEvent


@dataclass(frozen=True)
class AnnotationRecord:
    """One logged annotation event: who, when, what, and which earlier event it revised."""

    id: int
    trial_id: int
    annotator_id: int
    t_ns: int
    event: AnnotationEventModel
    revises: int | None


@dataclass
class Annotation:
    """One annotator's current annotation of one trial."""

    cut: int | None = None
    tags: dict[str, list[int]] = field(default_factory=dict)  # only tags with messages
    submitted: bool = False


@dataclass
class TrialAnnotations:
    """Every annotator's annotation of one trial, and the experimenter's adjudications."""

    by_annotator: dict[int, Annotation] = field(default_factory=dict)
    adjudicated: dict[str, int | bool] = field(default_factory=dict)  # item -> value

    def resolved_cut(self) -> tuple[int, str] | None:
        """The cut the exports use and where it comes from: the adjudicated one, else the one all
        annotators agree on; None while there is none or two annotators disagree unresolved."""
        if "cut" in self.adjudicated:
            return int(self.adjudicated["cut"]), "adjudicated"
        cuts = {a.cut for a in self.by_annotator.values() if a.cut is not None}
        return (cuts.pop(), "annotation") if len(cuts) == 1 else None

    def resolved_tags(self) -> dict[str, list[int]]:
        """Tags the dialog shows: adjudicated ones as decided, others where every annotator
        gave them; each with the messages any annotator anchored it to."""
        anchored: dict[str, set[int]] = {}
        for a in self.by_annotator.values():
            for tag, messages in a.tags.items():
                anchored.setdefault(tag, set()).update(messages)
        out = {}
        for tag, anchors in anchored.items():
            decided = self.adjudicated.get(tag)
            shown = bool(decided) if decided is not None else all(tag in a.tags for a in self.by_annotator.values())
            if shown:
                out[tag] = sorted(anchors)
        return dict(sorted(out.items()))


class AnnotationLog:
    def __init__(self, sessions: sessionmaker[Session]) -> None:
        self.sessions = sessions

    def append(self, trial_id: int, annotator_id: int, event: AnnotationEventModel, t_ns: int) -> AnnotationRecord:
        """Commit one event; it revises this annotator's last event of the same key, if any
        (adjudications are the trial's, whoever makes them)."""
        with self.sessions.begin() as db:
            earlier = [
                r
                for r in self._records(db, [trial_id])
                if r.event.key() == event.key() and (isinstance(event, Adjudicated) or r.annotator_id == annotator_id)
            ]
            row = AnnotationEvent(
                trial_id=trial_id,
                annotator_id=annotator_id,
                kind=event.kind,
                t_ns=t_ns,
                payload=event.payload(),
                revises=earlier[-1].id if earlier else None,
            )
            db.add(row)
            db.flush()
            return AnnotationRecord(row.id, trial_id, annotator_id, t_ns, event, row.revises)

    @classmethod
    def fold_in(cls, db: Session, trial_id: int) -> TrialAnnotations:
        """The trial's annotations, read in an open session (the exports')."""
        return fold(cls._records(db, [trial_id]))

    def records(self, trial_id: int) -> list[AnnotationRecord]:
        with self.sessions() as db:
            return self._records(db, [trial_id])

    def state(self, trial_id: int) -> TrialAnnotations:
        return fold(self.records(trial_id))

    def states(self, trial_ids: Iterable[int]) -> dict[int, TrialAnnotations]:
        ids = list(trial_ids)
        with self.sessions() as db:
            records = self._records(db, ids)
        return {i: fold(r for r in records if r.trial_id == i) for i in ids}

    @staticmethod
    def _records(db: Session, trial_ids: list[int]) -> list[AnnotationRecord]:
        """The trials' annotation events in the order they were logged."""
        rows = db.scalars(
            select(AnnotationEvent).where(AnnotationEvent.trial_id.in_(trial_ids)).order_by(AnnotationEvent.id)
        )
        return [
            AnnotationRecord(r.id, r.trial_id, r.annotator_id, r.t_ns, parse(r.kind, dict(r.payload)), r.revises)
            for r in rows
        ]


def fold(records: Iterable[AnnotationRecord]) -> TrialAnnotations:
    """The state a trial's annotation events add up to, in the order they were logged."""
    out = TrialAnnotations()
    for r in records:
        e = r.event
        if isinstance(e, Adjudicated):
            out.adjudicated[e.item] = e.value
            continue
        a = out.by_annotator.setdefault(r.annotator_id, Annotation())
        if isinstance(e, CutMarked):
            a.cut = e.message
        elif isinstance(e, Tagged):
            if e.messages:
                a.tags[e.tag] = sorted(set(e.messages))
            else:
                a.tags.pop(e.tag, None)
        elif isinstance(e, Submitted):
            a.submitted = True
    return out

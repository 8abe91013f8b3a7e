"""The annotation events: one pydantic model per kind, its fields the stored JSON payload.

Messages are numbered from 1 in the order the trial's log holds its chat (what the annotation
page shows). An annotator's later event of the same kind and key revises the earlier one; the
log keeps both (`AnnotationLog`).
"""

from __future__ import annotations

from collections.abc import Mapping
from enum import StrEnum
from typing import ClassVar

from pydantic import BaseModel, ConfigDict, Field


class Phenomenon(StrEnum):
    """The dialog phenomena the paper tagged a 20 % sample with."""

    NEEDS_HISTORY = "needs_history"
    COMMUNICATION_REPAIR = "communication_repair"
    RELOCALIZATION_REPAIR = "relocalization_repair"
    SURRENDER_CONTROL = "surrender_control"
    PERCEPTUAL_DIFFERENCES = "perceptual_differences"


# Each phenomenon's name as the paper writes it (a study's free tags are shown as they are).
TITLES: dict[str, str] = {
    Phenomenon.NEEDS_HISTORY: "Needs History",
    Phenomenon.COMMUNICATION_REPAIR: "Communication Repair",
    Phenomenon.RELOCALIZATION_REPAIR: "Re-localization Repair",
    Phenomenon.SURRENDER_CONTROL: "Surrender Control",
    Phenomenon.PERCEPTUAL_DIFFERENCES: "Perceptual Differences",
}


class AnnotationEventModel(BaseModel):
    model_config = ConfigDict(frozen=True, extra="ignore")
    kind: ClassVar[str]

    def key(self) -> str:
        """What a later event of this kind by the same annotator revises (one value per key)."""
        return self.kind

    def payload(self) -> dict[str, object]:
        return self.model_dump(mode="json")


class CutMarked(AnnotationEventModel):
    """The robot was localized after message `message` (0: before any message was sent)."""

    kind = "cut"
    message: int = Field(ge=0)


class Tagged(AnnotationEventModel):
    """A phenomenon (or a study's free tag) shown by these messages; none: the tag is withdrawn."""

    kind = "tag"
    tag: str = Field(min_length=1, max_length=60)
    messages: list[int] = []

    def key(self) -> str:
        return f"tag:{self.tag}"


class Submitted(AnnotationEventModel):
    """The annotator has finished this trial (it leaves their queue; they may still revise)."""

    kind = "submitted"


class Adjudicated(AnnotationEventModel):
    """The experimenter's decision where two annotators disagree: `item` is `cut` or a tag, and
    `value` the message number (cut) or whether the dialog shows the tag."""

    kind = "adjudicated"
    item: str = Field(min_length=1, max_length=64)
    value: int | bool

    def key(self) -> str:
        return f"adjudicated:{self.item}"


KINDS: dict[str, type[AnnotationEventModel]] = {cls.kind: cls for cls in (CutMarked, Tagged, Submitted, Adjudicated)}


def parse(kind: str, payload: Mapping[str, object]) -> AnnotationEventModel:
    cls = KINDS.get(kind)
    if cls is None:
        raise ValueError(f"unknown annotation event kind {kind!r}; expected one of {', '.join(KINDS)}")
    return cls.model_validate(payload)

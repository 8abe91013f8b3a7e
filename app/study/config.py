"""A study's configuration: a typed model kept as `DATA_DIR/studies/NAME.json`. Each change that
is saved bumps the version and keeps the version before it as `studies/NAME/vN.json`, so what a
participant consented to can always be read again."""

from __future__ import annotations

import json
import re
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import datetime, timedelta
from enum import StrEnum
from pathlib import Path
from typing import Annotated
from urllib.parse import quote

from pydantic import AwareDatetime, BaseModel, Field, HttpUrl, ValidationError, field_validator, model_validator

from app.i18n import Language

NAME_PATTERN = re.compile(r"^[a-z0-9][a-z0-9_-]{0,79}$")
RATING_SCALE = (1, 5)
PARAM_PATTERN = r"^[A-Za-z0-9_.-]{1,60}$"  # a query parameter's name in a panel's link
MAX_PANEL_ID = 200  # characters kept of each panel identifier (the columns' width)


class StudyConfigError(ValueError):
    """A study file or form that cannot be used; the message says what to change."""


class QuestionKind(StrEnum):
    difficulty = "difficulty"  # how hard the trial was, 1-5
    partner_helpfulness = "partner_helpfulness"  # the partner in their seat, 1-5 (RAIN's guide/navigator scores)
    free_text = "free_text"  # personal data: erased when the participant withdraws


class StudyOutcome(StrEnum):
    """How a participant's way through a study ended; each may have its own completion code."""

    completed = "completed"  # played the plan (`completion_code`)
    partial = "partial"  # "I have finished" before the plan, confirmed, after at least one trial
    no_partner = "no_partner"  # no partner within the lobby's time, or the partner never came
    withdrew = "withdrew"
    screened_out = "screened_out"  # by the experimenter
    timed_out = "timed_out"  # past the study's time_limit_s since consenting


class Question(BaseModel):
    id: str = Field(pattern=r"^[a-z0-9_]{1,40}$")
    kind: QuestionKind
    prompt: str = Field(min_length=1, max_length=500)


class Consent(BaseModel):
    version: str = Field(min_length=1, max_length=40)  # recorded with each agreement
    text: str = Field(min_length=1)


class RoleInstructions(BaseModel):
    commander: str = Field(min_length=1)
    driver: str = Field(min_length=1)


@dataclass(frozen=True)
class PanelIds:
    """A participant's identifiers on the panel that sent them (personal data: never on a public page)."""

    participant: str | None
    study: str | None
    session: str | None


class PanelLink(BaseModel):
    """A recruiting panel's link: the query parameters its study link carries (the participant's,
    the study's and the session's identifiers; Prolific's names by default) and its completion
    address, where `{code}` stands for the outcome's code."""

    participant_param: str = Field(default="PROLIFIC_PID", pattern=PARAM_PATTERN)
    study_param: str = Field(default="STUDY_ID", pattern=PARAM_PATTERN)
    session_param: str = Field(default="SESSION_ID", pattern=PARAM_PATTERN)
    completion_url: str | None = Field(default=None, max_length=500)  # e.g. Prolific's ...complete?cc={code}

    @field_validator("completion_url")
    @classmethod
    def _an_address_with_the_code(cls, url: str | None) -> str | None:
        if url is not None:
            if "{code}" not in url:
                raise ValueError("the completion address needs {code} where the outcome's code goes")
            try:
                HttpUrl(url.replace("{code}", "CODE"))
            except ValidationError:
                raise ValueError("the completion address is not an http(s) address") from None
        return url

    def read(self, query: Mapping[str, str]) -> PanelIds | None:
        """The panel's identifiers in a study link's query (None: the link carries none)."""
        ids = PanelIds(
            *(
                query.get(param, "").strip()[:MAX_PANEL_ID] or None
                for param in (self.participant_param, self.study_param, self.session_param)
            )
        )
        return None if ids == PanelIds(None, None, None) else ids

    def carried_by(self, query: Mapping[str, str]) -> bool:
        return any(p in query for p in (self.participant_param, self.study_param, self.session_param))

    def completion(self, code: str) -> str | None:
        """The panel's completion address for this code (None: the panel has none)."""
        return None if self.completion_url is None else self.completion_url.replace("{code}", quote(code, safe=""))


def default_questionnaire() -> list[Question]:
    return [
        Question(id="difficulty", kind=QuestionKind.difficulty, prompt="How hard was this trial? (1 easy - 5 hard)"),
        Question(
            id="partner",
            kind=QuestionKind.partner_helpfulness,
            prompt="How helpful was your partner in their seat? (1 not at all - 5 very)",
        ),
        Question(id="comments", kind=QuestionKind.free_text, prompt="Anything else you want to tell us?"),
    ]


class StudyConfig(BaseModel):
    name: str
    version: int = Field(default=1, ge=1)  # bumped by each saved change
    title: str = Field(min_length=1, max_length=200)
    consent: Consent
    instructions: RoleInstructions
    # A bundled maze (the same on every install) for each participant's first, unscored trial; None: no practice.
    practice_maze: str | None = "gen-000"
    practice_time_cap_s: float = Field(default=300.0, gt=0)  # the practice is stopped once its clock reaches this
    questionnaire: list[Question] = Field(default_factory=default_questionnaire)
    maze_pool: list[str] = Field(default_factory=list)  # maze names; empty: every maze the server has
    trials_per_participant: int = Field(default=5, ge=1, le=50)  # study trials a participant plays at most
    teams_per_participant: int = Field(default=5, ge=1, le=50)  # partners at most: the paper's 16 people in 41 teams
    max_participants: int | None = Field(default=None, ge=1)  # consents taken at most; None: no cap
    lobby_timeout_s: float = Field(default=600.0, gt=0)  # a participant waits this long for a partner
    join_timeout_s: float = Field(default=60.0, gt=0)  # a paired seat unopened this long: the trial is aborted
    lobby_presence_s: float = Field(default=10.0, gt=0)  # a lobby page silent this long has left (not paired)
    move_penalty_s: float | None = Field(default=None, ge=0)  # None: the server's ROBOTSLANG_MOVE_PENALTY_S
    completion_code: str | None = Field(default=None, max_length=80)  # the plan completed
    # The other outcomes' codes (a panel's, e.g. for partial or waiting pay); an outcome without one gets none.
    outcome_codes: dict[StudyOutcome, Annotated[str, Field(min_length=1, max_length=80)]] = Field(default_factory=dict)
    time_limit_s: float | None = Field(default=None, gt=0)  # since consenting; past it the lobby ends their way
    # Annotators' tags beside the paper's five phenomena (`app.annotation`); only these are accepted
    # for the study's trials.
    annotation_tags: list[Annotated[str, Field(pattern=r"^[a-z0-9][a-z0-9 _-]{0,59}$")]] = Field(default_factory=list)
    redirect_url: HttpUrl | None = None  # e.g. the recruiting site's completion link
    # The study closes (no one new consents from then); `purge_after_days` after it, the personal
    # data (real names, free text, panel identifiers) are deleted (`app.study.purge`).
    closed_at: AwareDatetime | None = None
    purge_after_days: int | None = Field(default=None, ge=0)
    webhook_url: HttpUrl | None = None  # receives the study's events as JSON (`app.study.webhook`)
    language: Language = Language.en  # of every page and message its participants see (`app.i18n`)
    panel: PanelLink | None = None  # participants recruited on a panel (Prolific, ...): its link and completion address

    @field_validator("name")
    @classmethod
    def _name_is_a_file_name(cls, name: str) -> str:
        if not NAME_PATTERN.match(name):
            raise ValueError(
                "a study name is 1-80 lowercase letters, digits, '-' or '_', starting with a letter or digit"
            )
        return name

    @field_validator("questionnaire")
    @classmethod
    def _ids_unique(cls, questions: list[Question]) -> list[Question]:
        ids = [q.id for q in questions]
        if len(set(ids)) != len(ids):
            raise ValueError(f"questionnaire item ids must be unique: {ids}")
        return questions

    @model_validator(mode="after")
    def _ends_somewhere(self) -> StudyConfig:
        if (
            self.completion_code is None
            and self.redirect_url is None
            and (self.panel is None or self.panel.completion_url is None)
        ):
            raise ValueError(
                "give a completion_code or a redirect_url (or a panel's completion_url): participants must be told "
                "they are done"
            )
        if StudyOutcome.completed in self.outcome_codes:
            raise ValueError("the plan's code is completion_code: outcome_codes holds the other outcomes'")
        return self

    def closed(self, now: datetime) -> bool:
        return self.closed_at is not None and now >= self.closed_at

    def purge_due(self, now: datetime) -> bool:
        """Its personal data are to be deleted by now (closed `purge_after_days` ago)."""
        return (
            self.closed_at is not None
            and self.purge_after_days is not None
            and now >= self.closed_at + timedelta(days=self.purge_after_days)
        )

    def code_for(self, outcome: StudyOutcome) -> str | None:
        """The completion code a participant whose way ended so is given (None: none)."""
        return self.completion_code if outcome is StudyOutcome.completed else self.outcome_codes.get(outcome)


def check_mazes(config: StudyConfig, bundled: set[str], known: set[str]) -> None:
    """The mazes a study names exist on this server; the practice maze is a bundled one."""
    if config.practice_maze is not None and config.practice_maze not in bundled:
        raise StudyConfigError(
            f"practice_maze {config.practice_maze!r} is not a bundled maze ({', '.join(sorted(bundled)[:4])}, ...)"
        )
    unknown = [m for m in config.maze_pool if m not in known]
    if unknown:
        raise StudyConfigError(f"maze_pool names mazes this server does not have: {', '.join(unknown[:10])}")


def parse(text: str) -> StudyConfig:
    """A study from its JSON text, or `StudyConfigError` saying each thing wrong."""
    try:
        return StudyConfig.model_validate_json(text)
    except ValidationError as err:
        problems = "; ".join(f"{'.'.join(map(str, e['loc'])) or 'study'}: {e['msg']}" for e in err.errors())
        raise StudyConfigError(f"the study is not valid: {problems}") from None


def template(name: str) -> StudyConfig:
    """A new study's starting point, for the experimenter to edit."""
    return StudyConfig(
        name=name,
        title=name,
        consent=Consent(
            version="1",
            text="You will chat with another participant to guide a robot through a maze. "
            "It takes about an hour. Your chat and the robot's moves are recorded under a code, not your name. "
            "You may stop at any time and withdraw your data.",
        ),
        instructions=RoleInstructions(
            commander="You see a map of the maze. Find where the robot is from what the Driver tells you, "
            "then guide it to the three targets in order.",
            driver="You see the robot's camera and move it. Describe what you see, follow the Commander, "
            "and claim a target when you think you are there.",
        ),
        completion_code="DONE-" + name.upper()[:20],
    )


class StudyFiles:
    """The studies kept under `root` (DATA_DIR/studies)."""

    def __init__(self, root: Path) -> None:
        self.root = root

    @classmethod
    def of(cls, data_dir: Path) -> StudyFiles:
        """The studies of the server whose data directory this is."""
        return cls(data_dir / "studies")

    def path(self, name: str) -> Path:
        if not NAME_PATTERN.match(name):
            raise LookupError(f"no study named {name[:80]!r}")
        return self.root / f"{name}.json"

    def names(self) -> list[str]:
        return sorted(p.stem for p in self.root.glob("*.json")) if self.root.is_dir() else []

    def load(self, name: str) -> StudyConfig:
        path = self.path(name)
        if not path.exists():
            raise LookupError(f"no study named {name!r}")
        config = parse(path.read_text())
        if config.name != name:
            raise StudyConfigError(f"{path} names the study {config.name!r}; rename one of them")
        return config

    def move_penalty_s(self, name: str, default: float) -> float:
        """The study's penalty per move where its file sets one, else `default` (the server's)."""
        try:
            own = self.load(name).move_penalty_s
        except LookupError:  # trials marked with a study's name that has no file
            own = None
        return default if own is None else own

    def language(self, name: str) -> Language:
        """The language of the study's participant pages (English for a name with no usable file)."""
        try:
            return self.load(name).language
        except (LookupError, StudyConfigError):
            return Language.en

    def version(self, name: str, version: int) -> StudyConfig:
        """The study as it was at `version` (the current one, or one kept before it)."""
        current = self.load(name)
        if current.version == version:
            return current
        kept = self.root / name / f"v{version}.json"
        if not kept.exists():
            raise LookupError(f"study {name!r} has no version {version}")
        return parse(kept.read_text())

    def save(self, config: StudyConfig) -> StudyConfig:
        """Write the study; a change to an existing one becomes the next version, the old kept."""
        path = self.path(config.name)
        if path.exists():
            old = self.load(config.name)
            if old.model_dump(exclude={"version"}) == config.model_dump(exclude={"version"}):
                return old
            (self.root / config.name).mkdir(parents=True, exist_ok=True)
            (self.root / config.name / f"v{old.version}.json").write_text(path.read_text())
            config = config.model_copy(update={"version": old.version + 1})
        else:
            self.root.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(config.model_dump(mode="json"), indent=2) + "\n")
        tmp.replace(path)
        return config

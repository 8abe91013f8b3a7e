"""Localization from Dialog History (LDH): where is the robot, given the dialog so far and the map.

The public benchmark ships no LDH file, so instances are derived from its NDH data, one per
trial: the trial's first target (jar) instance gives the true pose (`agent_pose`, the Driver's
start) and its dialog, which is the trial's first sub-dialog. The input is either that whole
sub-dialog (`full`) or its localization prefix, cut by the frozen rule `prefix-v1`
(`localization_prefix`). A folder exported by the platform (`app/export/ndh.py`) also holds
`LDH-data/<split>.json`, exact instances whose dialog ends at the Commander's first estimate;
where that file exists it is read instead (variant `exact`).
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from enum import StrEnum
from typing import NotRequired, TypedDict

from sim.tasks.benchmark import Benchmark, BenchmarkError, NDHInstance, scan_run

CUT_RULE = "prefix-v1"
HUMANS_TD_M = 0.446  # the paper's human study (8 people reading the dialogs)
FIRST_TARGET = "jar"  # every benchmark trial visits jar, mug, paddle in that order


class Variant(StrEnum):
    PREFIX = "prefix"  # derived: the first sub-dialog cut by CUT_RULE
    FULL = "full"  # derived: the whole first sub-dialog
    EXACT = "exact"  # recorded: the dialog up to the Commander's first estimate


Dialog = tuple[tuple[str, str], ...]  # (role: oracle|navigator, message)

# prefix-v1. Localization ends at the Commander's first movement instruction: an oracle message
# that is not a question and starts (after fillers such as "ok", "now", "so") with a motion verb,
# possibly behind "you need to" / "can you" ... The instruction itself is left out. An oracle
# message saying the Commander knows where the robot is ("I know where you are", "ok got it")
# ends localization too, and is kept.
_FILLER = r"(?:(?:ok(?:ay)?|alright|all right|great|good|perfect|now|so|then|yes|yeah|cool|nice|first|please|and|next)[\s,.!]*)*"
_VERBS = (
    r"(?:go|move|turn|take|make|head|drive|rotate|face|follow|back|keep|continue|proceed|come|spin"
    r"|reverse|start|get|do a|travel|pass|stay|look)"
)
_INSTRUCTION = re.compile(
    rf"^{_FILLER}(?:you (?:need|want|should|will|have) to |you can |try to "
    rf"|i want you to |can you |could you )?{_VERBS}\b",
    re.I,
)
_LOCALIZED = re.compile(
    r"\bi (?:know|think i know|see) (?:where you are|your location)\b"
    r"|\bi (?:found|located) you\b|^(?:ok(?:ay)?[\s,.]*)?got it\b",
    re.I,
)


def localization_prefix(dialog: Dialog) -> int:
    """How many turns of `dialog` the prefix-v1 rule keeps (all of them when no cue is found)."""
    for k, (role, message) in enumerate(dialog):
        if role != "oracle":
            continue
        text = message.strip()
        if _LOCALIZED.search(text):
            return k + 1
        if _INSTRUCTION.search(text) and not text.endswith("?"):
            return k
    return len(dialog)


class DialogTurn(TypedDict):
    role: str  # "oracle" (the Commander) or "navigator" (the Driver)
    message: str


class LDHInstanceJson(TypedDict):
    """One exported LDH instance, as `LDH-data/<split>.json` lists them (`app.export.ndh`)."""

    scan: str
    target: str
    agent_pose: list[float] | None  # the true pose (x, y, heading) when localization ended
    start_pose: list[float] | None
    commander_estimate: list[float | None] | None  # x, y and the heading where one was given
    localization_error_m: float | None
    localization_source: str
    localized_after_message: int
    all_targets: list[list[float]]
    dialog_history: list[DialogTurn]
    trial_id: str
    seats: dict[str, str]
    tags: NotRequired[dict[str, list[int]]]  # the dialog's phenomena, where annotated
    inst_idx: NotRequired[int]  # set when the split is written


@dataclass(frozen=True)
class LDHInstance:
    inst_idx: int
    run: str  # maze run folder
    x: float  # true position, metres
    y: float
    heading: float | None  # radians, where recorded
    dialog: Dialog
    variant: Variant


def derive(inst: NDHInstance, variant: Variant) -> LDHInstance:
    """The LDH instance of a trial from its first target's NDH instance."""
    if inst.previous_object is not None:
        raise BenchmarkError(f"instance {inst.inst_idx}: not a trial's first target (no start pose)")
    dialog = inst.dialog if variant == Variant.FULL else inst.dialog[: localization_prefix(inst.dialog)]
    return LDHInstance(
        inst_idx=inst.inst_idx,
        run=inst.run,
        x=inst.agent_pose[0],
        y=inst.agent_pose[1],
        heading=inst.start_heading,
        dialog=dialog,
        variant=variant,
    )


def exact_from_json(item: LDHInstanceJson) -> LDHInstance | None:
    """An exported LDH instance; None where the trial has no true pose (no overhead tracker)."""
    pose = item.get("agent_pose")
    if pose is None:
        return None
    return LDHInstance(
        inst_idx=int(item["inst_idx"]),
        run=scan_run(item["scan"]),
        x=float(pose[0]),
        y=float(pose[1]),
        heading=None if len(pose) < 3 or pose[2] is None else float(pose[2]),
        dialog=tuple((t["role"], t["message"]) for t in item["dialog_history"]),
        variant=Variant.EXACT,
    )


def load_split(bench: Benchmark, split: str, variant: Variant = Variant.PREFIX) -> list[LDHInstance]:
    """The split's LDH instances: the exported exact ones where `LDH-data/<split>.json` exists,
    else derived from the NDH split's first-target instances with `variant`."""
    path = bench.root / "LDH-data" / f"{split}.json"
    if path.exists():
        return [i for i in (exact_from_json(item) for item in json.loads(path.read_text())) if i is not None]
    if variant == Variant.EXACT:
        raise BenchmarkError(f"{path}: no exported LDH instances; use variant prefix or full")
    return [derive(inst, variant) for inst in bench.split(split) if inst.target == FIRST_TARGET]

"""The study editor's form: each field is named by its path in the study's JSON (`consent.text`,
`questionnaire.0.prompt`, `outcome_codes.partial`), so the form and the JSON are one study. A
submitted form is laid over the current study and checked as the JSON is (`parse`)."""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

from app.study.config import StudyConfig, parse

LINES = {"maze_pool", "annotation_tags"}  # lists edited one item a line
PANEL_ON = "panel_on"  # the checkbox: recruited on a panel (its fields apply only then)


def form_values(config: StudyConfig) -> dict[str, Any]:
    """What the form shows: the study as its JSON, with a blank questionnaire row to add an item."""
    values = config.model_dump(mode="json")
    values["questionnaire"].append({"id": "", "kind": "free_text", "prompt": ""})
    return values


def from_form(current: StudyConfig, form: Mapping[str, str]) -> tuple[dict[str, Any], StudyConfig | None, str | None]:
    """The submitted values laid over `current`, and the study they make (or why they make none):
    an empty field is unset, a questionnaire row without id and prompt is dropped."""
    values = current.model_dump(mode="json")
    values["panel"] = (values["panel"] or {}) if PANEL_ON in form else None
    for key, raw in form.items():
        text = raw.strip()
        head, *rest = key.split(".")
        if head not in values or (head == "panel" and values["panel"] is None):
            continue  # the CSRF token, the checkbox, a panel's fields while it is off
        if head in LINES:
            values[head] = [line.strip() for line in text.splitlines() if line.strip()]
        else:
            _put(values, [head, *rest], text or None)
    values["questionnaire"] = [q for q in values["questionnaire"] if q.get("id") or q.get("prompt")]
    values["outcome_codes"] = {k: v for k, v in values["outcome_codes"].items() if v}
    try:
        return values, parse(json.dumps(values)), None
    except ValueError as err:
        return values, None, str(err)


def _put(into: Any, path: list[str], value: str | None) -> None:
    """Set `value` at `path` (keys, and list indices as digits), making the rows a list lacks."""
    *parents, last = path
    for step in parents:
        if isinstance(into, list):
            if not step.isdigit() or int(step) > len(into):
                return  # a row is only added at the end (the form's blank one): no forged index grows the list
            if int(step) == len(into):
                into.append({})
            into = into[int(step)]
        else:
            into = into.setdefault(step, {})
    into[last] = value

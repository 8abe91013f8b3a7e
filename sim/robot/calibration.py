"""Calibration files a lab keeps (the front camera's, the overhead camera's): one error type and
one JSON reader and writer, so every calibration is refused in the same clear words."""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path


class CalibrationError(ValueError):
    """A calibration that is missing, unreadable, inconsistent or cannot be measured; the text says which."""


def save_json(data: Mapping[str, object], path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=2) + "\n")
    return path


def load_json(path: str | Path, what: str) -> dict[str, object]:
    """The JSON object in `path`, or `CalibrationError` naming the file and what is wrong with it."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except OSError as err:
        raise CalibrationError(f"{path}: cannot read ({err.strerror or err})") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise CalibrationError(f"{path}: not JSON ({err})") from None
    if not isinstance(data, dict):
        raise CalibrationError(f"{path}: not {what} (a JSON object is expected)")
    return data

"""deploy/compose.yaml's services, whose commands the deployment tests run."""

from __future__ import annotations

import sys
from pathlib import Path

import yaml

from tests.packaging.outside import REPO

DEPLOY = REPO / "deploy"
# The `robotslang` the services run: this venv's console script (its `app` is the checkout's).
CONSOLE_SCRIPTS = Path(sys.executable).parent


def compose_services() -> dict[str, dict]:
    """compose.yaml's services as Compose reads them: YAML merge keys (`<<: *server`) applied."""
    return yaml.safe_load((DEPLOY / "compose.yaml").read_text())["services"]


def service_command(service: dict, **options: str) -> list[str]:
    """A service's command as run on this machine: each `--option value` in `options` given its
    value here (`host="127.0.0.1"`), and Compose's `$$` (a literal `$`) unescaped for the shell."""
    command = [arg.replace("$$", "$") for arg in service["command"]]
    for name, value in options.items():
        flag = "--" + name.replace("_", "-")
        assert flag in command, f"{command} has no {flag}"
        command[command.index(flag) + 1] = value
    return command

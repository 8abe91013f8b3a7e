"""deploy/compose.yaml: the services a lab runs, as this repository's deployment test reads them
(tests/deploy/test_nginx.py runs their commands), and as Docker Compose reads them where it is
installed (`docker compose`, or Debian's `docker-compose`, which .ci/run installs)."""

from __future__ import annotations

import shutil
import subprocess

import pytest
import yaml

from tests.deploy.compose_file import DEPLOY, compose_services, service_command
from tests.packaging.outside import clean_env

SERVICES = {"postgres", "redis", "migrate", "server", "nginx"}
# What compose.yaml requires (`${VAR:?}`) to render, with stand-in values.
REQUIRED = {
    "POSTGRES_PASSWORD": "pw",
    "ROBOTSLANG_SECRET_KEY": "key",
    "ROBOTSLANG_ADMIN_PASSWORD": "admin-pw",
    "ROBOTSLANG_SERVER_NAME": "lab.example.org",
}


def test_the_services_a_lab_runs():
    services = compose_services()
    assert set(services) == SERVICES
    # Once, before the servers: the schema, then the first experimenter.
    (script,) = [arg for arg in services["migrate"]["command"] if arg.startswith("robotslang ")]
    assert script.split(" && ")[0] == "robotslang db upgrade"
    assert script.split(" && ")[1].startswith("robotslang admin create ")
    assert services["server"]["command"] == ["robotslang", "serve", "--host", "0.0.0.0", "--port", "8000"]
    assert services["server"]["deploy"]["replicas"] == "${ROBOTSLANG_SERVERS:-2}"
    # Every server process shares the database, Redis, the signing key and the frames' volume.
    shared = services["server"]["environment"]
    assert {"ROBOTSLANG_DATABASE_URL", "ROBOTSLANG_REDIS_URL", "ROBOTSLANG_SECRET_KEY"} <= set(shared)
    assert shared["ROBOTSLANG_REDIS_URL"].startswith("redis://redis:")
    assert "@postgres:5432/" in shared["ROBOTSLANG_DATABASE_URL"]
    assert services["server"]["volumes"] == services["migrate"]["volumes"]
    # nginx renders the template the deployment test renders, and publishes HTTP and HTTPS.
    assert (
        "./nginx/robotslang.conf.template:/etc/nginx/templates/robotslang.conf.template:ro"
        in (services["nginx"]["volumes"])
    )
    assert services["nginx"]["ports"] == ["80:80", "443:443"]


def docker_compose() -> list[str]:
    docker = shutil.which("docker")
    if docker and subprocess.run([docker, "compose", "version"], capture_output=True).returncode == 0:
        return [docker, "compose"]
    if legacy := shutil.which("docker-compose"):
        return [legacy]
    pytest.skip("neither `docker compose` nor `docker-compose` is installed (apt-get install docker-compose)")


def test_docker_compose_reads_the_same_services():
    out = subprocess.run(
        [*docker_compose(), "-f", str(DEPLOY / "compose.yaml"), "config"],
        env=clean_env(**REQUIRED),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert out.returncode == 0, out.stderr
    resolved = yaml.safe_load(out.stdout)["services"]
    assert set(resolved) == SERVICES
    ours = compose_services()
    # The commands the deployment test runs are the ones Compose would (`$$` being a literal `$`,
    # which a Compose version may print either way), with the variables the test sets.
    for name in ("migrate", "server"):
        assert [str(arg).replace("$$", "$") for arg in resolved[name]["command"]] == service_command(ours[name])
        assert set(resolved[name]["environment"]) == set(ours[name]["environment"]), name
    assert int(resolved["server"]["deploy"]["replicas"]) == 2
    assert set(resolved["nginx"]["environment"]) == set(ours["nginx"]["environment"])
    assert resolved["nginx"]["environment"]["ROBOTSLANG_SERVER_NAME"] == "lab.example.org"


def test_docker_compose_refuses_it_without_the_secrets():
    out = subprocess.run(
        [*docker_compose(), "-f", str(DEPLOY / "compose.yaml"), "config"],
        env=clean_env(**{k: v for k, v in REQUIRED.items() if k != "ROBOTSLANG_SECRET_KEY"}),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert out.returncode != 0 and "ROBOTSLANG_SECRET_KEY" in out.stderr

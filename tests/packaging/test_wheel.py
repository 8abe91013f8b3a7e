"""The built wheels, installed into a fresh venv outside the checkout, serve the platform and play a
demo trial, without torch.

The wheels are built offline (`python -m build --no-isolation`) from a copy of the checkout. The
fresh venv gets only the two wheels; their dependencies come from this interpreter's
site-packages through a .pth line (no download), and a meta-path hook there makes `import torch`
fail as on a machine without it.
"""

from __future__ import annotations

import re
import shutil
import sqlite3
import subprocess
import sys
import sysconfig
import time
from pathlib import Path

import httpx
import pytest

from tests.app.live import UNPACED_ENV, browser, page_csrf_token, submit_login
from tests.packaging.outside import REPO, clean_env, free_port

pytestmark = pytest.mark.slow


def build_wheels(tmp: Path) -> list[Path]:
    source, dist = tmp / "source", tmp / "dist"
    shutil.copytree(
        REPO,
        source,
        ignore=shutil.ignore_patterns(
            ".git", ".venv", "var", "runs", "build", "*.egg-info", "__pycache__", ".pytest_cache", "test-artifacts"
        ),
    )
    for project in (source / "robot_client", source):
        subprocess.run(
            [sys.executable, "-m", "build", "--wheel", "--no-isolation", "--outdir", str(dist), str(project)],
            check=True,
            capture_output=True,
            text=True,
        )
    return sorted(dist.glob("*.whl"))


@pytest.fixture(scope="module")
def venv(tmp_path_factory) -> Path:
    tmp = tmp_path_factory.mktemp("wheel")
    wheels = build_wheels(tmp)
    assert [w.name.split("-")[0] for w in wheels] == ["robotslang", "robotslang_robot"]
    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    python = venv / "bin" / "python"
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "--python",
            str(python),
            "install",
            "--quiet",
            "--no-index",
            "--no-deps",
            *map(str, wheels),
        ],
        check=True,
        env=clean_env(),
    )
    site = Path(
        subprocess.run(
            [str(python), "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
            check=True,
            capture_output=True,
            text=True,
        ).stdout.strip()
    )
    # Dependencies from this interpreter's site-packages, after the venv's own; no torch.
    deps = {sysconfig.get_path("purelib"), sysconfig.get_path("platlib")}
    shutil.copy(Path(__file__).with_name("no_torch.py"), site / "no_torch.py")
    (site / "zz_deps.pth").write_text("import no_torch\n" + "".join(f"{p}\n" for p in sorted(deps)))
    return venv


def run(venv: Path, *args: str, cwd: Path, **env: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(venv / "bin" / args[0]), *args[1:]],
        cwd=cwd,
        env=clean_env(**env),
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_the_installed_packages_come_from_the_wheels_and_torch_is_absent(venv, tmp_path):
    out = run(
        venv,
        "python",
        "-c",
        "import app, robot_client, sim; print(app.__file__); print(robot_client.__file__);"
        "print(sim.__file__)\ntry:\n import torch\nexcept ImportError: print('no torch')",
        cwd=tmp_path,
    ).stdout.splitlines()
    assert all(line.startswith(str(venv)) for line in out[:3]), out
    assert out[3] == "no torch"
    check = subprocess.run(
        [sys.executable, "-m", "pip", "--python", str(venv / "bin" / "python"), "check"],
        capture_output=True,
        text=True,
        env=clean_env(),
    )
    # Every dependency of both wheels is satisfied, without torch (pip check also reports on the
    # other packages of the environment lending the dependencies; those are not ours to judge).
    ours = [line for line in check.stdout.splitlines() if line.startswith(("robotslang ", "robotslang-robot "))]
    assert ours == [], check.stdout
    assert run(venv, "robotslang", "--version", cwd=tmp_path).stdout.strip() == "robotslang 0.1.0"


def test_the_installed_server_serves_pages_static_files_migrations_and_bundled_mazes(venv, tmp_path):
    data, port = tmp_path / "data", free_port()
    server = subprocess.Popen(
        [str(venv / "bin" / "robotslang"), "serve", "--port", str(port), "--data-dir", str(data)],
        cwd=tmp_path,
        env=clean_env(),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        url = f"http://127.0.0.1:{port}"
        deadline = time.time() + 60
        while True:
            assert server.poll() is None, server.stdout.read()
            try:
                if httpx.get(url + "/leaderboard", timeout=1).status_code == 200:
                    break
            except httpx.HTTPError:
                assert time.time() < deadline, "the installed server did not answer in 60 s"
                time.sleep(0.2)
        assert "<form" in httpx.get(url + "/").text
        css = httpx.get(url + "/static/style.css")
        assert css.status_code == 200 and css.headers["content-type"].startswith("text/css")
        with sqlite3.connect(data / "robotslang.db") as db:
            assert db.execute("select version_num from alembic_version").fetchone() == ("0011",)  # head
        server.terminate()
        first_lines = server.communicate(timeout=20)[0]
        password = re.search(r"experimenter 'admin' created with password (\S+)", first_lines).group(1)
    finally:
        if server.poll() is None:
            server.kill()
            server.wait()
    # Logged in, the experimenter picks from the mazes bundled in the wheel.
    mazes = trial_form_mazes(venv, tmp_path, url, "admin", password, "--port", str(port), "--data-dir", str(data))
    assert {f"gen-{i:03d}" for i in range(12)} <= mazes


def trial_form_mazes(venv: Path, cwd: Path, url: str, user: str, password: str, *serve_args: str) -> set[str]:
    """The mazes the trial form offers, from `robotslang serve *serve_args`: logged in with the home
    page's form, two participants made into a team (the form shows once there is one)."""
    server = subprocess.Popen(
        [str(venv / "bin" / "robotslang"), "serve", *serve_args], cwd=cwd, env=clean_env(), stdout=subprocess.DEVNULL
    )
    try:
        with browser(url) as client:
            deadline = time.time() + 60
            while True:
                try:
                    page = submit_login(client, user, password)
                    break
                except httpx.HTTPError:
                    assert server.poll() is None and time.time() < deadline
                    time.sleep(0.2)
            assert page.url.path == "/experimenter"
            client.headers["X-CSRF-Token"] = page_csrf_token(page.text)
            for name in ("Ada", "Ben"):
                client.post("/experimenter/participants", data={"name": name})
            page = client.post("/experimenter/teams", data={"name": "A & B", "member_a": 1, "member_b": 2})
            return set(re.findall(r'<option value="([\w-]+)" data-layout=', page.text))
    finally:
        server.terminate()
        server.wait(timeout=20)


def test_the_installed_server_takes_the_benchmark_data_dir_and_port_flags(venv, tmp_path, benchmark_path):
    data, port = tmp_path / "lab-data", free_port()
    made = run(
        venv,
        "robotslang",
        "admin",
        "create",
        "lab",
        "--password",
        "lab-password",
        cwd=tmp_path,
        ROBOTSLANG_DATA_DIR=str(data),
    )
    assert made.returncode == 0, made.stdout + made.stderr
    mazes = trial_form_mazes(
        venv,
        tmp_path,
        f"http://127.0.0.1:{port}",
        "lab",
        "lab-password",
        *("--port", str(port), "--data-dir", str(data), "--benchmark", str(benchmark_path)),
    )
    # A benchmark run is a maze where it has the fixed map (a few have only the raw one).
    benchmark_mazes = {p.parents[1].name for p in (benchmark_path / "mazedata").glob("Run_*/maze/maze.map-fixed.png")}
    assert benchmark_mazes and benchmark_mazes <= mazes and "gen-000" in mazes


def test_the_installed_demo_plays_a_trial(venv, tmp_path):
    env = {"ROBOTSLANG_DATA_DIR": str(tmp_path / "d"), **UNPACED_ENV}  # unpaced: no waiting
    out = run(venv, "robotslang", "demo", "--trials", "1", cwd=tmp_path, **env)
    assert out.returncode == 0, out.stdout + out.stderr
    assert ": finished," in out.stderr

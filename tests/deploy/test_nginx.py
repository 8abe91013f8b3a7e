"""deploy/ as a lab runs it, on one machine: PostgreSQL and Redis, compose.yaml's migrate
command, two of its server processes (its `serve` command on loopback ports), and Debian's nginx
with deploy/nginx/robotslang.conf.template, given the variables compose.yaml gives it,
terminating TLS in front of them. A demo trial plays through the proxy over wss://, its
Commander and Driver reaching different processes. Where Docker Compose is installed, it checks
compose.yaml too."""

from __future__ import annotations

import asyncio
import json
import re
import shutil
import ssl
import subprocess
import sys
import time
from pathlib import Path

import httpx
import pytest
import websockets

from app.main import build_services
from app.security import SeatTokens
from app.settings import Settings
from bench.live import ServerProcess, free_port, make_trial
from tests.app.live import UNPACED_ENV, page_csrf_token
from tests.deploy.compose_file import CONSOLE_SCRIPTS, DEPLOY, compose_services, service_command
from tests.packaging.outside import REPO, clean_env

NGINX = shutil.which("nginx") or "/usr/sbin/nginx"
SECRET = "deploy-test-secret"


def render(template: Path, values: dict[str, str]) -> str:
    """envsubst as the nginx image runs it: only the named ${VARIABLES}, nginx's own $vars stay."""
    text = template.read_text()
    for name, value in values.items():
        text = text.replace("${" + name + "}", value)
    left = re.findall(r"\$\{\w+\}", text)
    assert not left, f"{template.name}: no value for {left}"
    return text


def self_signed(tmp: Path) -> tuple[Path, Path]:
    cert, key = tmp / "cert.pem", tmp / "key.pem"
    subprocess.run(
        [
            "openssl",
            "req",
            "-x509",
            "-newkey",
            "rsa:2048",
            "-nodes",
            "-days",
            "1",
            "-subj",
            "/CN=127.0.0.1",
            "-addext",
            "subjectAltName=IP:127.0.0.1",
            "-keyout",
            str(key),
            "-out",
            str(cert),
        ],
        check=True,
        capture_output=True,
    )
    return cert, key


class Nginx:
    """Debian's nginx as a user process: its own prefix, pid, logs and temp paths under `tmp`."""

    def __init__(self, tmp: Path, site: str) -> None:
        self.prefix = tmp / "nginx"
        for sub in ("logs", "temp"):
            (self.prefix / sub).mkdir(parents=True, exist_ok=True)
        (self.prefix / "robotslang.conf").write_text(site)
        temp = self.prefix / "temp"
        (self.prefix / "nginx.conf").write_text(f"""
worker_processes 1;
pid {self.prefix}/nginx.pid;
error_log {self.prefix}/logs/error.log warn;
events {{ worker_connections 256; }}
http {{
    log_format upstream '$request_uri $status $upstream_addr';
    access_log {self.prefix}/logs/access.log upstream;
    client_body_temp_path {temp}/body;
    proxy_temp_path {temp}/proxy;
    fastcgi_temp_path {temp}/fastcgi;
    uwsgi_temp_path {temp}/uwsgi;
    scgi_temp_path {temp}/scgi;
    include {self.prefix}/robotslang.conf;
}}
""")
        self.conf = self.prefix / "nginx.conf"

    def __enter__(self) -> Nginx:
        check = subprocess.run(
            [NGINX, "-p", str(self.prefix), "-c", str(self.conf), "-t"], capture_output=True, text=True
        )
        assert check.returncode == 0, check.stderr
        subprocess.run([NGINX, "-p", str(self.prefix), "-c", str(self.conf)], check=True)
        return self

    def __exit__(self, *exc) -> None:
        subprocess.run([NGINX, "-p", str(self.prefix), "-c", str(self.conf), "-s", "quit"], check=False)
        pid = self.prefix / "nginx.pid"
        deadline = time.time() + 10
        while pid.exists() and time.time() < deadline:
            time.sleep(0.1)

    def upstreams(self, path_prefix: str) -> list[tuple[str, str]]:
        """(status, upstream address) of every logged request under `path_prefix`."""
        lines = (self.prefix / "logs" / "access.log").read_text().splitlines()
        return [
            (status, addr) for uri, status, addr in (line.split(" ") for line in lines) if uri.startswith(path_prefix)
        ]


@pytest.fixture
def nginx_available():
    if not Path(NGINX).exists():
        pytest.skip("nginx is not installed (apt-get install -y nginx; .ci/run installs it)")


@pytest.mark.slow
def test_two_servers_behind_nginx_play_a_trial_over_tls(tmp_path, postgres_url, redis_url, nginx_available):
    services = compose_services()
    env = {
        **clean_env(),
        "PATH": f"{CONSOLE_SCRIPTS}:{clean_env()['PATH']}",
        "PYTHONPATH": str(REPO),
        "ROBOTSLANG_DATABASE_URL": postgres_url,
        "ROBOTSLANG_REDIS_URL": redis_url,
        "ROBOTSLANG_SECRET_KEY": SECRET,
        "ROBOTSLANG_DATA_DIR": str(tmp_path / "data"),
        **UNPACED_ENV,
        "ROBOTSLANG_TRUSTED_PROXIES": '["127.0.0.1"]',  # nginx here; compose.yaml names its container
    }
    # What compose.yaml configures the platform with, this test configures too.
    for name in ("migrate", "server"):
        assert {k for k in services[name]["environment"] if k.startswith("ROBOTSLANG_")} <= set(env) | {
            "ROBOTSLANG_ADMIN",
            "ROBOTSLANG_ADMIN_PASSWORD",
        }, name
    # compose.yaml's migrate command (schema, first experimenter), then two of its server processes.
    migrate = subprocess.run(
        service_command(services["migrate"]),
        env={**env, "ROBOTSLANG_ADMIN": "admin", "ROBOTSLANG_ADMIN_PASSWORD": "deploy-test-pw"},
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert migrate.returncode == 0, migrate.stdout + migrate.stderr
    ports = [free_port(), free_port()]
    servers = [
        ServerProcess(env, port=port, argv=service_command(services["server"], host="127.0.0.1", port=str(port)))
        for port in ports
    ]
    cert, key = self_signed(tmp_path)
    http_port, https_port = free_port(), free_port()
    nginx_values = {
        "ROBOTSLANG_UPSTREAM_SERVERS": " ".join(f"server 127.0.0.1:{port};" for port in ports),
        "ROBOTSLANG_LISTEN_ADDRESS": "127.0.0.1",
        "ROBOTSLANG_HTTP_PORT": str(http_port),
        "ROBOTSLANG_HTTPS_PORT": str(https_port),
        "ROBOTSLANG_SERVER_NAME": "127.0.0.1",
        "ROBOTSLANG_TLS_CERT": str(cert),
        "ROBOTSLANG_TLS_KEY": str(key),
    }
    # The nginx service's variables are the template's: the ones rendered here.
    assert set(services["nginx"]["environment"]) == set(nginx_values)
    site = render(DEPLOY / "nginx" / "robotslang.conf.template", nginx_values)
    try:
        for server in servers:
            server.start()
        with Nginx(tmp_path, site) as nginx:
            proxy = f"https://127.0.0.1:{https_port}"
            plain = httpx.get(f"http://127.0.0.1:{http_port}/leaderboard")
            assert plain.status_code == 301 and plain.headers["location"] == f"{proxy}/leaderboard"
            # Over TLS: HSTS from nginx, and the server's cookies are __Host- and Secure (it believes
            # nginx's X-Forwarded-Proto), so an experimenter's session works through the proxy.
            with httpx.Client(
                base_url=proxy,
                verify=ssl.create_default_context(cafile=str(cert)),
                headers={"Origin": proxy},
                timeout=60,  # a loaded machine's first page
            ) as browser:
                home = browser.get("/")
                assert home.headers["strict-transport-security"] == "max-age=31536000"
                assert re.match(
                    r"__Host-robotslang_browser=[^;]+; Path=/; HttpOnly; SameSite=Strict; Secure$",
                    home.headers["set-cookie"],
                )
                login = browser.post(
                    "/login",
                    data={"name": "admin", "password": "deploy-test-pw", "csrf_token": page_csrf_token(home.text)},
                )
                assert login.status_code == 303 and login.headers["location"] == "/experimenter"
                assert "__Host-robotslang_session=" in login.headers["set-cookie"]
                assert "secure" in login.headers["set-cookie"].lower() and "Path=/" in login.headers["set-cookie"]
                assert browser.get("/experimenter").status_code == 200, "the __Host- session is read back"
            # The demo's seats (Commander, then Driver) connect through the proxy, trusting its cert.
            demo = subprocess.run(
                [sys.executable, "-c", "from app.cli import main; main()", "demo", "--trials", "1", "--server", proxy],
                env={**env, "SSL_CERT_FILE": str(cert)},
                cwd=tmp_path,
                capture_output=True,
                text=True,
                timeout=300,
            )
            assert demo.returncode == 0, demo.stdout + demo.stderr
            assert re.search(r"trial 1: .*: finished,", demo.stderr), demo.stderr
            seats = nginx.upstreams("/ws/play")
            assert len(seats) == 2 and {status for status, _ in seats} == {"101"}
            assert {addr for _, addr in seats} == {f"127.0.0.1:{s.port}" for s in servers}

            # A browser's socket carries its page's Origin: through the proxy it is still its own host.
            # (On a trial still open: the demo's trial is over, and its links closed with it.)
            services = build_services(
                Settings(database_url=postgres_url, data_dir=tmp_path / "data", secret_key=SECRET)
            )
            trial_id = make_trial(services, services.mazes.names()[0], team="Browser team")
            services.engine.dispose()

            async def browser_seat() -> dict:
                token = SeatTokens(SECRET).issue(trial_id, "commander")
                async with websockets.connect(
                    f"wss://127.0.0.1:{https_port}/ws/play?token={token}",
                    origin=proxy,
                    ssl=ssl.create_default_context(cafile=cert),
                ) as ws:
                    while (message := json.loads(await asyncio.wait_for(ws.recv(), 10)))["type"] != "welcome":
                        pass  # its own `connect` event comes first
                    return message

            assert asyncio.run(browser_seat())["type"] == "welcome"
    finally:
        for server in servers:
            server.stop()

"""In headless Chromium: a page served from another port of 127.0.0.1 (the same site, so the
experimenter's SameSite cookie goes along) cannot create participants or abort a trial; and the
platform's own pages run under its Content-Security-Policy without a single violation."""

from __future__ import annotations

import http.server
import threading

import pytest
from sqlalchemy import select

from app.db.models import Experimenter, Participant, Trial
from app.security import hash_password
from bench.live import free_port

pytestmark = pytest.mark.browser

ATTACK = """<!doctype html><html><body>
<form id="f" method="post" action="{target}/experimenter/participants"><input name="name" value="Mallory"></form>
<script>
  fetch("{target}/experimenter/trials/{trial}/abort", {{method: "POST", mode: "no-cors", credentials: "include"}})
    .finally(() => document.getElementById("f").submit());
</script></body></html>"""


class AttackerSite:
    """A page of another origin of the same site: 127.0.0.1 on its own port."""

    def __init__(self, page: str) -> None:
        body = page.encode()

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_GET(self):  # noqa: N802
                self.send_response(200)
                self.send_header("Content-Type", "text/html")
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, *args):
                pass

        self.server = http.server.ThreadingHTTPServer(("127.0.0.1", free_port()), Handler)
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}/attack.html"
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)

    def __enter__(self) -> AttackerSite:
        self.thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self.server.shutdown()
        self.server.server_close()


def test_a_page_on_another_port_cannot_act_with_the_experimenters_cookie(browser, server, trials):
    services = server.services
    with services.db.begin() as db:
        db.add(Experimenter(name="eve", password_hash=hash_password("correct horse")))
    trial = trials.new()
    violations: list[str] = []
    page = browser.new_context().new_page()
    page.on("console", lambda m: violations.append(m.text) if "Content Security Policy" in m.text else None)
    page.goto(server.url + "/")
    page.fill("input[name=name]", "eve")
    page.fill("input[name=password]", "correct horse")
    page.click("#login")
    page.wait_for_url(server.url + "/experimenter")
    # The dashboard's own forms and scripts work: a participant added, a robot registered by fetch.
    page.fill("input[aria-label='Participant name']", "Ada")
    page.click("#add-participant")
    page.locator("#participants li", has_text="Ada").wait_for()
    page.fill("input[aria-label='Robot name']", "rover A")
    page.click("#add-robot")
    page.wait_for_selector("#robot-token:not([hidden]) .token:not(:empty)")
    for role in ("commander", "driver"):
        page.goto(trial.play_url(role))
        page.locator("#status", has_text="waiting for").wait_for()

    with AttackerSite(ATTACK.format(target=server.url, trial=trial.id)) as attacker:
        page.goto(attacker.url)
        page.wait_for_url(lambda url: url.startswith(server.url))  # the forged form was answered
    with services.db() as db:
        names = set(db.scalars(select(Participant.name)))
        assert "Ada" in names and "Mallory" not in names
        assert db.get(Trial, trial.id).phase == "waiting"
    assert "refused" in page.content()
    assert violations == []

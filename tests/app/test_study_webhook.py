"""A study's webhook against a real server and a real HTTP receiver on 127.0.0.1: the study's
events (a pair made, its trial over, a withdrawal) arrive as JSON naming participants by their
codes only; a receiver that is slow or down delays no participant, and its failure is logged."""

from __future__ import annotations

import json
import logging
import queue
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

from app.study.config import StudyFiles
from tests.app.live import experimenter_client
from tests.app.test_study import end, join, poll
from tests.app.test_study_paths import study


@contextmanager
def receiver(hold: threading.Event | None = None) -> Iterator[tuple[str, queue.Queue[dict], queue.Queue[dict]]]:
    """An HTTP server on a free loopback port that keeps each JSON body POSTed to /hook: in `held`
    as it arrives, in `received` once answered (with `hold`, not before it is set)."""
    received: queue.Queue[dict] = queue.Queue()
    held: queue.Queue[dict] = queue.Queue()

    class Hook(BaseHTTPRequestHandler):
        def do_POST(self) -> None:
            body = self.rfile.read(int(self.headers["Content-Length"]))
            item = {"path": self.path, "type": self.headers["Content-Type"], **json.loads(body)}
            held.put(item)
            if hold is not None:
                hold.wait(60)
            received.put(item)
            self.send_response(204)
            self.end_headers()

        def log_message(self, *args: object) -> None:
            pass

    httpd = ThreadingHTTPServer(("127.0.0.1", 0), Hook)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{httpd.server_address[1]}/hook", received, held
    finally:
        httpd.shutdown()
        httpd.server_close()


def test_the_studys_events_reach_its_webhook_as_json_with_codes_only(server):
    with receiver() as (url, received, _):
        StudyFiles.of(server.settings.data_dir).save(
            study("pilot", practice_maze=None, trials_per_participant=1, webhook_url=url)
        )
        (ann, ann_code), (bob, bob_code) = join(server, "pilot", "Ann Real"), join(server, "pilot", "Bob Real")
        assert poll(ann)["state"] == "waiting"
        seat = poll(bob)
        paired = received.get(timeout=10)
        assert paired["path"] == "/hook" and paired["type"] == "application/json"
        assert paired["event"] == "paired" and paired["study"] == "pilot" and paired["study_version"] == 1
        assert {paired["commander"], paired["driver"]} == {ann_code, bob_code} and paired["practice"] is False
        assert paired[seat["role"]] == bob_code
        end(server, experimenter_client(server.services, server.url))
        over = received.get(timeout=10)
        assert (over["event"], over["trial_id"], over["phase"]) == ("trial_ended", paired["trial_id"], "aborted")
        ann.post("/study/pilot/withdraw", data={"confirm": "yes"})
        gone = received.get(timeout=10)
        assert (gone["event"], gone["participant"]) == ("withdrawal", ann_code)
        for event in (paired, over, gone):
            assert "Real" not in json.dumps(event), "no real name in what leaves the server"
        assert received.empty()


def test_a_slow_or_failing_webhook_delays_no_participant_and_is_logged(server, caplog):
    hold = threading.Event()  # the receiver answers nothing until the participants are served
    with receiver(hold) as (url, received, held):
        StudyFiles.of(server.settings.data_dir).save(study("pilot", practice_maze=None, webhook_url=url))
        (ann, _), (bob, _) = join(server, "pilot"), join(server, "pilot")
        assert poll(ann)["state"] == "waiting"
        assert poll(bob)["state"] == "seated"
        assert held.get(timeout=10)["event"] == "paired"  # its delivery is out, and held
        cat, _ = join(server, "pilot")
        assert "You have withdrawn" in cat.post("/study/pilot/withdraw", data={"confirm": "yes"}).text
        assert received.empty(), "participants were answered while the webhook still waited"
        hold.set()
        assert received.get(timeout=10)["event"] == "paired"

    caplog.set_level(logging.WARNING, logger="robotslang.study.webhook")
    StudyFiles.of(server.settings.data_dir).save(study("pilot", practice_maze=None, webhook_url=url))  # gone now
    dan, _ = join(server, "pilot")
    assert "You have withdrawn" in dan.post("/study/pilot/withdraw", data={"confirm": "yes"}).text
    deadline = time.monotonic() + 15
    while not any("webhook" in r.getMessage() and "failed" in r.getMessage() for r in caplog.records):
        assert time.monotonic() < deadline, "the failed delivery is logged"
        time.sleep(0.1)

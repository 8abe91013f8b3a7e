"""`python -m bench.load`, as a script that holds its figures against issue 15's goals runs it: a real
server process, real seats over loopback, and the `--json` line's keys. Latencies are printed, never
asserted (they depend on the machine); what is asserted is what the bench offers and what the
server must not lose."""

from __future__ import annotations

import json
import subprocess
import sys

from bench.live import free_port
from tests.conftest import REPO

KEYS = {
    "chat_p50_ms",
    "chat_p99_ms",
    "move_to_frame_p50_ms",
    "move_to_frame_p99_ms",
    "events_per_s",
    "lost",
    "unanswered",
    "server_cpu",
    "server_rss_mb",
}


def test_load_bench_offers_one_chat_and_one_move_per_trial_second_and_loses_nothing():
    trials, duration = 4, 4.0
    out = subprocess.run(
        [sys.executable, "-m", "bench.load", "--trials", str(trials), "--duration", str(duration)]
        + ["--warmup", "1", "--port", str(free_port()), "--json"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=300,
        check=True,
    )
    figures = json.loads(out.stdout.strip().splitlines()[-1])
    assert figures.keys() >= KEYS
    assert figures["trials"] == trials and figures["workers"] == 1
    assert figures["lost"] == 0 and figures["unanswered"] == 0
    # Each trial keeps to its own deadlines: one chat and one move a second, within the one send
    # a trial may make at either edge of the measured window.
    window = figures["duration_s"]
    for sent in (figures["chats"], figures["moves"]):
        assert trials * (window - 1) <= sent <= trials * (window + 1)
    # Committed in the window: per trial-second at least the chat, the move's request, its result
    # and its frame.
    assert figures["events"] >= 4 * trials * (window - 1)

"""`python -m bench.load`, as a script that holds its figures against issue 15's goals runs it: a real
server process, real seats over loopback, and the `--json` line's keys. Latencies are printed, never
asserted (they depend on the machine); what is asserted is what the bench offers and what the
server must not lose, with no lower bound that a loaded machine could miss."""

from __future__ import annotations

import json
import subprocess
import sys

from bench.live import free_port
from tests.packaging.outside import REPO

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
    # Each trial keeps to its own deadlines: at most one chat and one move a second (a slow machine
    # can only delay sends), and every trial sent both in the window.
    window = figures["duration_s"]
    for sent in (figures["chats"], figures["moves"]):
        assert trials <= sent <= trials * (window + 1)
    # The rate a script reads is the events committed in the window over its length (both rounded
    # to a tenth in the JSON).
    assert figures["events"] >= trials
    assert abs(figures["events_per_s"] * window - figures["events"]) <= 0.05 * (window + figures["events_per_s"]) + 0.01


WALK_KEYS = KEYS | {
    "pattern",
    "mazes",
    "maze_count",
    "first_move_p50_ms",
    "first_move_p99_ms",
    "first_moves",
    "handshake_p50_ms",
    "handshake_p99_ms",
    "handshake_max_ms",
    "handshakes",
    "handshakes_failed",
    "welcome_p50_ms",
    "welcome_p99_ms",
    "connected_within_goal",
    "processes",
    "load_average_before",
    "load_average",
    "beliefs",
}


def test_walking_trials_on_distinct_mazes_opening_at_once_lose_nothing():
    trials, duration = 24, 8.0  # past the 16 mazes a render process once kept; long enough to bump
    out = subprocess.run(
        [sys.executable, "-m", "bench.load", "--trials", str(trials), "--duration", str(duration)]
        + ["--pattern", "walk", "--mazes", "distinct", "--open-at-once"]
        + ["--warmup", "2", "--port", str(free_port()), "--json"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=600,
        check=True,
    )
    figures = json.loads(out.stdout.strip().splitlines()[-1])
    assert figures.keys() >= WALK_KEYS
    assert figures["pattern"] == "walk" and figures["mazes"] == "distinct" and figures["open_at_once"]
    assert figures["maze_count"] == trials  # every trial on a maze of its own
    assert figures["handshakes"] == 2 * trials and figures["handshakes_failed"] == 0
    assert figures["first_moves"] == trials  # each trial's first move came back with its frame
    assert figures["lost"] == 0 and figures["unanswered"] == 0
    kinds = [p["kind"] for p in figures["processes"]]
    assert kinds.count("server") == 1 and "render" in kinds  # each process of the server, with its peak
    assert all(p["peak_rss_mb"] > 0 for p in figures["processes"])
    assert figures["watchers"] == 1 and figures["beliefs"] == 1  # the watched trial's filter ran, alone


AGENT_KEYS = KEYS | {
    "agent_drivers",
    "agent_reply_p50_ms",
    "agent_reply_p95_ms",
    "agent_replies",
    "agent_unreplied",
    "agent_moves",
    "agent_chat_p99_ms",
}


def test_agent_drivers_are_seated_spoken_to_and_lose_nothing():
    trials, agents = 8, 3
    out = subprocess.run(
        [sys.executable, "-m", "bench.load", "--trials", str(trials), "--agent-drivers", str(agents)]
        + ["--duration", "10", "--warmup", "2", "--port", str(free_port()), "--json"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=300,
        check=True,
    )
    figures = json.loads(out.stdout.strip().splitlines()[-1])
    assert figures.keys() >= AGENT_KEYS
    assert figures["trials"] == trials and figures["agent_drivers"] == agents
    assert figures["lost"] == 0 and figures["unanswered"] == 0
    # The agents answered the bench's Commanders and carried out their instructions.
    assert figures["agent_replies"] >= agents and figures["agent_moves"] > 0
    assert "agent Drivers" in out.stderr

"""A burst of wrong logins against `robotslang serve` on loopback: does the server keep answering?

Sends N concurrent wrong logins (half for a known account, half for unknown names) while a
probe fetches `GET /` one request after another. Prints the probe's latency before and during
the burst, the burst's answers and duration, the server's peak resident memory, and the mean
answer time of known and unknown names, alone and in the burst (which should match: unknown
names are checked against a dummy hash). The login rate limits are raised so every attempt reaches the password check.

    python -m bench.login --logins 200
"""

from __future__ import annotations

import argparse
import asyncio
import collections
import os
import re
import tempfile
import time
from pathlib import Path

import httpx
import numpy as np
from rich.console import Console

from app.db.models import Experimenter
from app.main import build_services
from app.security import hash_password
from app.settings import Settings
from bench.live import ServerProcess, settings_env
from bench.report import percentile, rss_mb

console = Console()


async def probe(http: httpx.AsyncClient, stop: asyncio.Event) -> list[float]:
    latencies = []
    while not stop.is_set():
        started = time.perf_counter()
        assert (await http.get("/")).status_code == 200
        latencies.append(time.perf_counter() - started)
        await asyncio.sleep(0.02)
    return latencies


async def burst(url: str, logins: int, pid: int) -> None:
    limits = httpx.Limits(max_connections=logins + 10, max_keepalive_connections=logins + 10)
    async with httpx.AsyncClient(base_url=url, headers={"Origin": url}, timeout=600, limits=limits) as http:
        token = re.search(r'name="csrf-token" content="([^"]+)"', (await http.get("/")).text).group(1)
        idle_stop = asyncio.Event()
        idle = asyncio.create_task(probe(http, idle_stop))
        await asyncio.sleep(2)
        idle_stop.set()
        idle_latency = await idle

        # One at a time: what a single check costs, for a known and for an unknown name.
        alone: dict[str, list[float]] = collections.defaultdict(list)
        for i in range(20):
            name = "eve" if i % 2 else f"stranger{i}"
            started = time.perf_counter()
            await http.post("/login", data={"name": name, "password": "wrong", "csrf_token": token})
            alone["known" if i % 2 else "unknown"].append(time.perf_counter() - started)

        answers: dict[str, list[tuple[int, float]]] = collections.defaultdict(list)

        async def guess(i: int) -> None:
            name = "eve" if i % 2 else f"nobody{i}"
            started = time.perf_counter()
            answer = await http.post("/login", data={"name": name, "password": f"guess {i}", "csrf_token": token})
            answers["known" if i % 2 else "unknown"].append((answer.status_code, time.perf_counter() - started))

        peak = before = rss_mb(pid)
        stop = asyncio.Event()
        during = asyncio.create_task(probe(http, stop))
        started = time.perf_counter()
        guesses = asyncio.gather(*(guess(i) for i in range(logins)))
        while not guesses.done():
            peak = max(peak, rss_mb(pid))
            await asyncio.sleep(0.05)
        await guesses
        took = time.perf_counter() - started
        stop.set()
        during_latency = await during

    statuses = collections.Counter(s for rows in answers.values() for s, _ in rows)
    console.print(f"{logins} concurrent wrong logins: answered in {took:.1f} s, statuses {dict(statuses)}")
    for label, values in (("idle", idle_latency), ("during the burst", during_latency)):
        ms = np.array(values) * 1000
        console.print(
            f"GET / {label}: {len(ms)} requests, p50 {percentile(ms, 50):.1f} ms, "
            f"p99 {percentile(ms, 99):.1f} ms, max {ms.max():.1f} ms"
        )
    console.print(f"server RSS: {before:.0f} MiB before the burst, peak {peak:.0f} MiB during it")
    for label in ("known", "unknown"):
        console.print(
            f"{label} name: {np.mean(alone[label]) * 1000:.0f} ms a login alone (mean of 10), "
            f"{np.mean([t for _, t in answers[label]]):.1f} s in the burst (waiting for a check slot)"
        )
    console.print(f"load average now: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--logins", type=int, default=200)
    parser.add_argument("--port", type=int, default=8766)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        limits = {"login_limit_per_account": "100000/minute", "login_limit_per_address": "100000/minute"}
        settings = Settings(data_dir=Path(tmp) / "var", secret_key="bench", database_url=None, **limits)
        services = build_services(settings)
        with services.db.begin() as db:
            db.add(Experimenter(name="eve", password_hash=hash_password("correct horse")))
        services.engine.dispose()
        server = ServerProcess(settings_env(settings), port=args.port).start()
        try:
            asyncio.run(burst(server.url, args.logins, server.proc.pid))
        finally:
            server.stop()


if __name__ == "__main__":
    main()

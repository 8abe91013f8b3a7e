"""`app.mazes.Kept`: what trials opening together in threads rely on."""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

from app.mazes import Kept


class Thing:  # a weakly referenceable value, as a maze is
    def __init__(self, name: str) -> None:
        self.name = name


def test_mazes_of_different_trials_load_side_by_side():
    """While one maze loads, another trial's maze loads too (one lock for all queued a crowd)."""
    both_loading = threading.Barrier(2, timeout=10)

    def make(name: str) -> Thing:
        both_loading.wait()  # raises BrokenBarrierError if the other is never made meanwhile
        return Thing(name)

    kept = Kept(make, size=4)
    with ThreadPoolExecutor(2) as pool:
        made = list(pool.map(kept, ["a", "b"]))
    assert [t.name for t in made] == ["a", "b"]


def test_trials_opening_together_on_one_maze_share_one_load():
    calls: list[str] = []
    release = threading.Event()

    def make(name: str) -> Thing:
        calls.append(name)
        release.wait(10)
        return Thing(name)

    kept = Kept(make, size=4)
    with ThreadPoolExecutor(4) as pool:
        futures = [pool.submit(kept, "a") for _ in range(4)]
        release.set()
        made = [f.result(timeout=10) for f in futures]
    assert calls == ["a"]
    assert all(t is made[0] for t in made)

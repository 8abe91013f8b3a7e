"""Mazes prepared before anyone waits (`app.preparation`): a server on an empty cache prepares every
maze in the background and says how far it is; a second start on the same cache prepares
nothing; a cache of another version is prepared again; a new trial's maze goes first; and
`robotslang mazes prepare` does it on demand. On the bundled mazes only (a dozen)."""

from __future__ import annotations

import asyncio
import logging
import threading
import time
from concurrent.futures import Future
from pathlib import Path

from app.preparation import Preparation, prepare_maze, prepared_version
from bench.live import team_trial
from sim.core import observations
from sim.core.maze import map_files
from sim.tasks.generator import generate_maze
from sim.tasks.library import MazeLibrary
from tests.app.live import cli, experimenter_client, platform_settings

PREPARED_WITHIN_S = 120  # a dozen mazes take a few seconds; a loaded machine many more


def wait_prepared(server) -> None:
    deadline = time.monotonic() + PREPARED_WITHIN_S
    while not server.services.mazes.preparation.progress().done:
        assert time.monotonic() < deadline, f"mazes still not prepared: {server.services.mazes.preparation.progress()}"
        time.sleep(0.1)


def preparation_log(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name == "app.preparation"]


def markers(cache: Path) -> dict[str, float]:
    return {p.name: p.stat().st_mtime_ns for p in (cache / "prepared").iterdir()}


def test_a_server_on_an_empty_cache_prepares_every_maze_and_shows_how_far_it_is(start_server, tmp_path, caplog):
    caplog.set_level(logging.INFO, logger="app.preparation")
    cache = tmp_path / "cache"
    server = start_server(cache_dir=cache)
    names = server.services.mazes.names()
    wait_prepared(server)

    # The last maze may be ready a moment before the sweep logs its end: wait for that line.
    done = f"mazes: {len(names)} of {len(names)} mazes ready ({len(names)} prepared here)"
    deadline = time.monotonic() + PREPARED_WITHIN_S
    while not any(line.startswith(done) for line in preparation_log(caplog)):
        assert time.monotonic() < deadline, preparation_log(caplog)
        time.sleep(0.1)
    assert f"mazes: preparing what trials need of {len(names)} mazes in {cache}" in preparation_log(caplog)
    # The maps were read for the grouping into layouts by the builders, before the preparing.
    log = preparation_log(caplog)
    reading = log.index(f"mazes: reading {len(names)} maps to group them into layouts")
    assert any(line.startswith("mazes: maps read in ") for line in log[reading:])
    assert reading < log.index(f"mazes: preparing what trials need of {len(names)} mazes in {cache}")
    page = experimenter_client(server.services, server.url).get("/experimenter").text
    assert f"All {len(names)} mazes are ready" in page
    # Each maze's graph, rays and scene are in the cache, and a marker of this version says so.
    assert len(markers(cache)) == len(names) and all(m.endswith(prepared_version()) for m in markers(cache))
    for folder in ("navgraph", "rays", "scene"):
        assert len(list((cache / folder).iterdir())) == len(names), folder


def test_robotslang_serve_prints_how_far_the_preparation_is(server_process, tmp_path):
    # What a lab sees in the terminal it started the server from: the platform's INFO lines too.
    # The bundled mazes only, whatever benchmark this shell's environment names: a few seconds.
    server = server_process(platform_settings(tmp_path, cache_dir=tmp_path / "cache", benchmark=None)).start()
    n = len(server.services.mazes.names())
    done = f"INFO app.preparation: mazes: {n} of {n} mazes ready ({n} prepared here) in "
    deadline = time.monotonic() + PREPARED_WITHIN_S
    while done not in (output := server.log()):
        assert time.monotonic() < deadline, output
        time.sleep(0.2)
    assert f"INFO app.preparation: mazes: reading {n} maps to group them into layouts" in output


def test_a_second_start_on_the_same_cache_prepares_nothing(start_server, tmp_path, caplog):
    cache = tmp_path / "cache"
    first = start_server(cache_dir=cache)
    wait_prepared(first)
    first.stop()
    before = {p: p.stat().st_mtime_ns for p in cache.rglob("*") if p.is_file()}

    caplog.set_level(logging.INFO, logger="app.preparation")
    second = start_server(cache_dir=cache)
    wait_prepared(second)
    n = len(second.services.mazes.names())
    assert any(line.startswith(f"mazes: {n} of {n} mazes ready (0 prepared here)") for line in preparation_log(caplog))
    assert not any(line.startswith("mazes: reading") for line in preparation_log(caplog))  # grouped already
    assert {p: p.stat().st_mtime_ns for p in cache.rglob("*") if p.is_file()} == before  # nothing written


def test_a_cache_of_another_version_is_prepared_again_in_the_background(start_server, tmp_path, caplog):
    """As after an upgrade that changed the ray tables: the old version's files are there, the
    current version's are not; the server builds them from its start, not at a seat's request."""
    cache = tmp_path / "cache"
    first = start_server(cache_dir=cache)
    wait_prepared(first)
    first.stop()
    current, older = f"-v{observations.CACHE_VERSION}", f"-v{observations.CACHE_VERSION - 1}"
    for rays in (cache / "rays").iterdir():
        rays.rename(rays.with_name(rays.name.replace(current, older)))
    old_version = prepared_version().replace(
        f"rays{observations.CACHE_VERSION}", f"rays{observations.CACHE_VERSION - 1}"
    )
    for marker in (cache / "prepared").iterdir():
        marker.rename(marker.with_name(marker.name.replace(prepared_version(), old_version)))

    caplog.set_level(logging.INFO, logger="app.preparation")
    second = start_server(cache_dir=cache)
    wait_prepared(second)
    n = len(second.services.mazes.names())
    assert any(
        line.startswith(f"mazes: {n} of {n} mazes ready ({n} prepared here)") for line in preparation_log(caplog)
    )
    assert sum(current in p.name for p in (cache / "rays").iterdir()) == n


def test_a_new_trials_maze_is_prepared_before_the_rest_of_the_library(start_server, tmp_path, trials):
    cache = tmp_path / "cache"
    server = start_server(cache_dir=cache)
    names = server.services.mazes.names()
    trials.new(server, names[-1])  # the library's last: the sweep would reach it last
    wait_prepared(server)
    library = server.services.mazes.library
    done_at = {
        name: (cache / "prepared" / f"{library.maps_key(name)}-{prepared_version()}").stat().st_mtime_ns
        for name in names
    }
    assert sorted(names, key=done_at.get).index(names[-1]) < len(names) // 2


def test_reading_the_library_for_layouts_waits_while_new_trials_mazes_are_built(tmp_path, monkeypatch):
    """On a fresh install the server reads every map to group the library into layouts; new
    trials' mazes are built first, the reading waits for them (it shared the builders with them,
    and a crowd's seats waited longer), and reads none of them: building one reads it too."""
    library = MazeLibrary(cache=False, cache_dir=tmp_path)
    names = library.names()
    preparation = Preparation(lambda: library, None, tmp_path, builders=1)
    submitted: list[tuple[str, bool]] = []
    builds: dict[str, Future] = {}

    def submit(name: str, only_signature: bool = False) -> tuple[Future, None]:
        submitted.append((name, only_signature))
        future: Future = Future()
        if only_signature:
            future.set_result(False)
        else:
            builds[name] = future
        return future, None

    monkeypatch.setattr(preparation, "_submit", submit)

    def built(name: str) -> None:
        deadline = time.monotonic() + 60  # a bound on a loaded machine, not a timing
        while name not in builds:
            assert time.monotonic() < deadline, submitted
            time.sleep(0.01)
        builds[name].set_result(True)

    preparation.first(names[0])
    preparation.first(names[1])
    reading = threading.Thread(target=preparation.sign)
    reading.start()
    built(names[0])
    time.sleep(0.2)
    assert all(not signature for _, signature in submitted), submitted  # a new trial's maze still waits
    built(names[1])
    reading.join(60)  # a loaded machine: a bound, not a timing
    assert not reading.is_alive()
    assert [name for name, signature in submitted if signature] == names[2:]


def test_mazes_prepare_prepares_into_the_cache_dir_with_a_progress_bar(tmp_path):
    """The bundled mazes and a benchmark's (here a benchmark folder of one maze)."""
    benchmark, cache = tmp_path / "benchmark", tmp_path / "cache"
    generate_maze(1000, name="Run_1").save(benchmark / "mazedata" / "Run_1")
    n = len(MazeLibrary(benchmark))
    prepare = ("mazes", "prepare", "--benchmark", str(benchmark), "--cache-dir", str(cache))
    done = cli(*prepare, env={})
    assert done.returncode == 0, done.stderr
    assert "Preparing mazes" in done.stdout and "100%" in done.stdout
    assert f"{n} of {n} mazes ready in {cache} ({n} prepared now)" in done.stdout
    assert len(markers(cache)) == n and len(list((cache / "rays").iterdir())) == n

    again = cli(*prepare, env={})
    assert again.returncode == 0 and f"{n} of {n} mazes ready in {cache} (0 prepared now)" in again.stdout


def test_a_seat_whose_maze_is_not_prepared_yet_is_welcomed_once_it_is_built(start_server, tmp_path, trials):
    """A trial made before its maze is prepared (not through the dashboard, which puts it first):
    the Driver's seat waits for its maze's build, then is welcomed on its graph."""
    cache = tmp_path / "cache"
    server = start_server(cache_dir=cache)
    maze = server.services.mazes.names()[-1]  # the library's last: the sweep reaches it last
    with server.services.db.begin() as db:
        trial = trials.of(
            team_trial(db, "Team A", maze, server.services.mazes.names(), server.services.clock.now_ns()), on=server
        )

    async def driver_welcome() -> dict:
        async with trial.seat("driver") as driver:
            return await driver.wait_for(lambda m: m.get("type") == "welcome", timeout=PREPARED_WITHIN_S)

    assert asyncio.run(driver_welcome())["type"] == "welcome"
    library = server.services.mazes.library
    assert (cache / "prepared" / f"{library.maps_key(maze)}-{prepared_version()}").exists()


def test_the_grouping_into_layouts_reads_a_maze_being_prepared_last_and_decodes_each_map_once(tmp_path, monkeypatch):
    """On a fresh install the server groups the library into layouts while the builders prepare
    new trials' mazes: a maze they have in hand is read once they have cached it, not decoded by both."""
    from sim.core import maze as maze_module

    expected = MazeLibrary(cache=False).layouts(cache_dir=tmp_path / "other")
    cache = tmp_path / "cache"
    library = MazeLibrary(cache=False, cache_dir=cache)
    in_hand = library.names()[0]
    decoded: list[Path] = []
    read = maze_module.read_label_png
    monkeypatch.setattr(maze_module, "read_label_png", lambda path: decoded.append(path) or read(path))

    class Builders:
        def in_hand(self, name: str) -> bool:
            return name == in_hand

        def ensure(self, name: str) -> None:
            prepare_maze(library, name, cache)

    assert library.layouts(cache_dir=cache, preparing=Builders()) == expected
    files = [f for name in library.names() for f in map_files(library.path(name)) if f is not None]
    assert sorted(decoded) == sorted(files)  # each map decoded once
    assert {f.parent.parent.name for f in decoded[-2:]} == {in_hand}  # the one in hand, last


def test_grouping_a_prepared_library_loads_no_maze(tmp_path, monkeypatch):
    """The server groups its library at each start where the grouping of these maps is not stored
    (a maze added, say): with the mazes prepared, it reads their signatures and loads no maze's grids."""
    from sim.core.maze import Maze

    cache = tmp_path / "cache"
    library = MazeLibrary(cache=False, cache_dir=cache)
    for name in library.names():
        prepare_maze(library, name, cache)
    expected = library.layouts(cache_dir=tmp_path / "other")
    for grouping in (cache / "layouts").glob("grouping-*.json"):
        grouping.unlink()

    def loaded(*args, **kwargs):
        raise AssertionError("a maze was loaded to group the library")

    monkeypatch.setattr(Maze, "from_dir", loaded)
    assert library.layouts(cache_dir=cache) == expected


def test_the_dashboard_answers_while_a_fresh_install_still_groups_the_benchmarks_mazes(
    start_server, tmp_path, benchmark_path
):
    # The warm-up decodes every map to group the library into layouts (12 s for the benchmark's
    # 178 runs): the dashboard, asked at once, lists the mazes and says it is grouping them.
    server = start_server(cache_dir=tmp_path / "cache", benchmark=benchmark_path)
    page = experimenter_client(server.services, server.url).get("/experimenter")
    assert page.status_code == 200
    assert "Grouping the mazes into physical layouts" in page.text
    assert '<option value="Run_114" data-layout="Run_114">' in page.text

"""The trial form compares mazes by physical layout: a team that has played Run_114 is never
offered, nor given, Run_117 or Run_119 (the same table under other names)."""

from __future__ import annotations

import html
import re
import shutil

import pytest

from sim.tasks.library import MazeLibrary
from tests.app.live import experimenter_client, open_seats, platform_settings

ONE_TABLE = ("Run_114", "Run_117", "Run_119")
OTHERS = ("Run_146", "Run_152")  # same walls as each other, landmarks elsewhere: two layouts


@pytest.fixture
def small_benchmark(benchmark_path, tmp_path):
    """A benchmark folder holding five of the public benchmark's maps (grouping all 172 takes a minute)."""
    root = tmp_path / "bench"
    for run in ONE_TABLE + OTHERS:
        shutil.copytree(benchmark_path / "mazedata" / run / "maze", root / "mazedata" / run / "maze")
    return root


def _error(page: str) -> str:
    found = re.search(r'<p class="error" role="alert" id="error">(.*?)</p>', page)
    return html.unescape(found.group(1)) if found else ""


def _trials(page: str) -> list[tuple[str, str]]:
    """(trial id, maze cell text) of each row of the trials table."""
    rows = re.findall(r'<tr data-trial="(\d+)">.*?<td class="maze">(.*?)</td>', page, re.S)
    return [(tid, re.sub(r"<[^>]+>", "", cell).strip()) for tid, cell in rows]


def played(server, client, trial_id: int) -> str:
    """The Commander loads the map (the layout is seen), then the experimenter aborts the trial."""
    open_seats(server, trial_id, "commander")
    return client.post(f"/experimenter/trials/{trial_id}/abort").text


def test_a_team_that_played_a_layout_is_never_offered_it_again(tmp_path, small_benchmark, start_server):
    settings = platform_settings(tmp_path, benchmark=small_benchmark)
    MazeLibrary(small_benchmark).layouts(cache_dir=settings.cache_dir)  # as `robotslang mazes layouts` does
    server = start_server(settings)
    client = experimenter_client(server.services, server.url)
    for name in ("Ada", "Ben"):
        client.post("/experimenter/participants", data={"name": name})
    client.post("/experimenter/teams", data={"name": "Pair", "member_a": 1, "member_b": 2})
    page = client.get("/experimenter").text
    assert 'data-layout="Run_114">Run_117 (layout Run_114)</option>' in page
    client.post("/experimenter/trials", data={"team_id": 1, "maze": "Run_114"})
    page = played(server, client, 1)
    for twin in ("Run_117", "Run_119"):
        page = client.post("/experimenter/trials", data={"team_id": 1, "maze": twin}).text
        assert _error(page) == (f"maze '{twin}' is layout Run_114, which team 'Pair' has already seen as Run_114")
    offered = []
    while "suggested maze" in page:  # the suggestion, taken each time: each other layout once
        offered.append(re.search(r"suggested maze ([^,)]+)\)", page).group(1))  # its own layout: none named
        client.post("/experimenter/trials", data={"team_id": 1})
        page = played(server, client, len(offered) + 1)
    others = [name for name in MazeLibrary(small_benchmark).names() if name not in ONE_TABLE]
    assert sorted(offered) == sorted(others)
    page = client.post("/experimenter/trials", data={"team_id": 1}).text
    assert _error(page) == "team 'Pair' has seen every layout in the library"
    assert sorted(maze for _, maze in _trials(page)) == sorted(["Run_114", *others])
    # A new member's team has seen Run_114's layout through Ada: Run_117 is refused for it too.
    client.post("/experimenter/participants", data={"name": "Cy"})
    client.post("/experimenter/teams", data={"name": "Ada and Cy", "member_a": 1, "member_b": 3})
    page = client.post("/experimenter/trials", data={"team_id": 2, "maze": "Run_117"}).text
    assert "already seen as Run_114" in _error(page)

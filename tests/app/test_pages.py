"""What the pages answer, over real HTTP on loopback: the Commander's map with its landmarks
(bundled and benchmark mazes), HTML error pages for people and JSON for scripts, controls on a
missing or ended trial, agents offered only where they can start, and a trial's exports."""

from __future__ import annotations

import asyncio
import json
import re
from pathlib import Path

import cv2
import httpx
import numpy as np
import pytest
from mcap.reader import make_reader

from app.db.models import Experimenter, Trial
from app.demo.runner import Demo
from app.export.mcap import DERIVED_TOPICS
from app.mazes import Mazes, commander_map
from app.security import hash_password
from sim.core.geometry import world_to_pixel
from sim.core.labels import LABEL_BGR, OBJECT_LABELS
from tests.app.live import platform_settings

HTML = {"Accept": "text/html,application/xhtml+xml"}


def landmark_pixels(png: bytes) -> dict[str, int]:
    image = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
    return {label.word: int(np.all(image == LABEL_BGR[label], axis=-1).sum()) for label in OBJECT_LABELS}


def assert_landmarks_at_their_places(mazes: Mazes, name: str) -> None:
    maze = mazes.load(name)
    image = commander_map(maze)
    for label in OBJECT_LABELS:
        col, row = world_to_pixel(*maze.objects[label.word])
        assert tuple(image[int(round(float(row))), int(round(float(col)))]) == LABEL_BGR[label], (name, label)
    # The walls-only map the navigation graph is built on keeps no object colour.
    walls = maze.image(walls_only=True)
    assert not any(np.all(walls == LABEL_BGR[label], axis=-1).any() for label in OBJECT_LABELS)


def test_every_bundled_maze_map_marks_the_three_landmarks(tmp_path):
    mazes = Mazes(platform_settings(tmp_path, benchmark=None))  # the bundled ones, whatever the environment says
    for name in mazes.names():
        assert_landmarks_at_their_places(mazes, name)
        assert all(n > 500 for n in landmark_pixels(mazes.map_png(name)).values()), name


def test_benchmark_maze_map_marks_the_three_landmarks(tmp_path, benchmark_path):
    mazes = Mazes(platform_settings(tmp_path, benchmark=benchmark_path))
    bundled = set(Mazes(platform_settings(tmp_path, benchmark=None)).names())
    benchmark = [n for n in mazes.names() if n not in bundled]
    assert benchmark, "the benchmark adds mazes"
    for name in benchmark[:3]:
        assert_landmarks_at_their_places(mazes, name)


def log_in(server) -> httpx.Client:
    with server.services.db.begin() as db:
        db.add(Experimenter(name="eve", password_hash=hash_password("correct horse")))
    # Patient as a browser: the first dashboard loads the shipped Driver to check it (torch: seconds).
    headers = {"Origin": server.url, "Referer": server.url + "/"}
    client = httpx.Client(base_url=server.url, headers=headers, timeout=60)
    client.post("/login", data={"name": "eve", "password": "correct horse", **csrf(client, "/")})
    return client


def csrf(client: httpx.Client, page: str) -> dict[str, str]:
    """The page's CSRF token (where the server issues one), as the page's own forms send it."""
    found = re.search(r'name="csrf-token" content="([^"]*)"', client.get(page, headers=HTML).text)
    token = found.group(1) if found else ""
    if token:
        client.headers["X-CSRF-Token"] = token
    return {"csrf_token": token} if token else {}


def test_people_get_html_error_pages_and_scripts_get_json(server):
    page = httpx.get(server.url + "/no/such/page", headers=HTML)
    assert page.status_code == 404 and page.headers["content-type"].startswith("text/html")
    assert 'id="error-page"' in page.text and "Page not found" in page.text
    bad_link = httpx.get(server.url + "/play/not-a-token", headers=HTML)
    assert bad_link.status_code == 403 and "Ask your experimenter for a new join link" in bad_link.text
    assert httpx.get(server.url + "/no/such/page").json() == {"detail": "Not Found"}
    # The favicon is served, so no page logs a 404 for it.
    assert httpx.get(server.url + "/favicon.ico").headers["content-type"].startswith("image/svg")

    client = log_in(server)
    missing = client.get("/experimenter/trials/999", headers=HTML)
    assert missing.status_code == 404 and "trial 999 does not exist" in missing.text
    assert client.get("/experimenter/trials/not-a-number", headers=HTML).status_code == 404


def test_controls_answer_404_on_a_missing_trial_and_refuse_what_does_not_apply(server, trials):
    client = log_in(server)
    token = csrf(client, "/experimenter")
    for action in ("pause", "resume", "abort"):
        assert client.post(f"/experimenter/trials/999/{action}", data=token).status_code == 404
    trial = trials.new()
    # A waiting trial cannot be paused; it can be aborted, and then nothing applies.
    paused = client.post(f"/experimenter/trials/{trial.id}/pause", data=token, follow_redirects=True)
    assert "pause does not apply" in paused.text
    client.post(f"/experimenter/trials/{trial.id}/abort", data=token)
    with server.services.db() as db:  # committed by the time the answer came
        assert db.get(Trial, trial.id).phase == "aborted"
    page = client.get(f"/experimenter/trials/{trial.id}", headers=HTML).text
    assert all(re.search(rf'control-{a}"\s+hidden', page) for a in ("pause", "resume", "abort"))
    again = client.post(f"/experimenter/trials/{trial.id}/abort", data=token, follow_redirects=True)
    assert "aborted: abort does not apply" in again.text


@pytest.mark.settings(seq2seq_checkpoint=Path("/nonexistent/missing.pt"))
def test_an_agent_that_cannot_start_is_not_offered_and_is_refused_with_its_reason(server, trials):
    client = log_in(server)
    trials.new()  # a team, so the trial form shows
    page = client.get("/experimenter").text
    options = dict(re.findall(r'<option value="((?:agent|oracle):[a-z0-9_]+)"([^>]*)>', page))
    for offered in ("agent:dialog", "agent:random", "oracle:shortest"):
        assert offered in options and "disabled" not in options[offered]
    assert "stops after 300 moves per target or 15 minutes of trial clock" in page  # the agent's caps
    assert "disabled" in options["agent:seq2seq"] and "unavailable:" in page
    token = csrf(client, "/experimenter")
    refused = client.post(
        "/experimenter/trials",
        follow_redirects=True,
        data={"team_id": 1, "driver": "agent:seq2seq", "targets": "random", **token},
    )
    assert "cannot start" in refused.text and "agent:seq2seq" in refused.text


def test_replay_page_links_its_mcap_and_ndh_exports(tmp_path, start_server):
    settings = platform_settings(tmp_path, min_move_interval_s=0.0)
    (result,) = asyncio.run(Demo(settings, seed=5, pace_s=0.0).run(1))
    assert result.phase == "finished"
    server = start_server(settings)  # on the demo's database
    client = log_in(server)
    page = client.get(f"/experimenter/trials/{result.trial_id}/replay").text
    mcap_url = re.search(r'id="export-mcap" href="([^"]+)"', page).group(1)
    ndh_url = re.search(r'id="export-ndh" href="([^"]+)"', page).group(1)
    log = client.get(f"/experimenter/trials/{result.trial_id}/replay.json").json()

    mcap = client.get(mcap_url)
    assert mcap.status_code == 200 and "attachment" in mcap.headers["content-disposition"]
    (tmp_path / "t.mcap").write_bytes(mcap.content)
    with open(tmp_path / "t.mcap", "rb") as stream:
        messages = [m for _, c, m in make_reader(stream).iter_messages() if c.topic not in DERIVED_TOPICS]
    assert len(messages) == len(log["events"])

    ndh = json.loads(client.get(ndh_url).content)
    assert [i["target"] for i in ndh["ndh"]] == log["trial"]["targets"]
    assert len(ndh["ldh"]) == 1
    assert client.get("/experimenter/trials/999/export.mcap").status_code == 404
    assert httpx.get(server.url + mcap_url, follow_redirects=False).status_code == 303, "experimenters only"

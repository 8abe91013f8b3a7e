"""The replay page in headless Chromium: one timeline drives chat, frames and the map."""

from __future__ import annotations

import asyncio
from pathlib import Path

import pytest

from app.db.models import Experimenter
from app.demo.runner import Demo
from app.security import hash_password
from app.settings import Settings
from tests.app.live import wait_js
from tests.e2e.pages import CHROMIUM

# A test artifact, like the other browser tests' (docs/img/replay.png is a copy of one).
SCREENSHOT = Path(__file__).resolve().parents[2] / "test-artifacts" / "replay.png"

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def server(tmp_path_factory, start_module_server):
    if not CHROMIUM.exists():
        pytest.skip(f"{CHROMIUM} not found: the replay page is checked in Debian's chromium")
    settings = Settings(
        data_dir=tmp_path_factory.mktemp("replay") / "var", secret_key="replay-test", min_move_interval_s=0.0
    )
    demo = Demo(settings, seed=11, pace_s=0.02)  # a timeline of several seconds, to pause part-way
    (result,) = asyncio.run(demo.run(1))
    assert result.phase == "finished", result
    with demo.db.begin() as db:
        db.add(Experimenter(name="eve", password_hash=hash_password("correct horse")))
    return start_module_server(settings), result.trial_id


def log_in(page, url: str) -> None:
    page.goto(url + "/")
    page.fill("input[name=name]", "eve")
    page.fill("input[name=password]", "correct horse")
    page.locator("form[action='/login'] button").click()
    page.wait_for_url(url + "/experimenter")


def scrub_to(page, ms: float) -> None:
    page.eval_on_selector(
        "#scrub", "(e, v) => { e.value = String(v); e.dispatchEvent(new Event('input')); }", round(ms)
    )


def shown(page) -> dict:
    return page.evaluate("""() => ({
        chat: [...document.querySelectorAll('#chat li')].filter(li => !li.classList.contains('hidden')).length,
        frame: document.getElementById('frame').dataset.frameId || null,
        poses: Number(document.getElementById('map').dataset.poses),
        estimates: Number(document.getElementById('map').dataset.estimates),
        events: Number(document.getElementById('replay').dataset.events),
    })""")


def expected_at(log: dict, ms: float) -> dict:
    """What the page must show at `ms` on its timeline, from the log itself."""
    events = log["events"]
    t0 = next(e for e in events if e["kind"] != "trial_created")["t_ns"]
    done = [e for e in events if max(0.0, (e["t_ns"] - t0) / 1e6) <= ms]
    frames = [e for e in done if e["kind"] == "frame" and e["payload"].get("source", "driver") == "driver"]
    return {
        "chat": sum(e["kind"] == "chat" for e in done),
        "frame": str(frames[-1]["payload"]["frame_id"]) if frames else None,
        "poses": sum(e["kind"] == "pose" for e in done),
        "estimates": sum(e["kind"] == "localization" for e in done),
        "events": len(done),
    }


def test_replay_plays_the_log_in_sync(server, browser):
    running, trial_id = server
    page = browser.new_page(viewport={"width": 1500, "height": 950})
    log_in(page, running.url)
    page.locator(f"tr[data-trial='{trial_id}'] a.replay").click()
    page.wait_for_selector("#replay[data-ready='1']")
    log = page.evaluate(f"() => fetch('/experimenter/trials/{trial_id}/replay.json').then(r => r.json())")
    end = float(page.get_attribute("#scrub", "max"))
    assert end > 0

    scrub_to(page, 0)
    assert shown(page) == expected_at(log, 0)
    for fraction in (0.3, 0.6, 1.0):
        scrub_to(page, end * fraction)
        assert shown(page) == expected_at(log, round(end * fraction)), fraction
    final = shown(page)
    assert final["chat"] == sum(e["kind"] == "chat" for e in log["events"]) > 0
    assert final["events"] == len(log["events"])
    assert "finished" in page.inner_text("#status")
    wait_js(page, "() => document.getElementById('frame').naturalWidth === 320")

    scrub_to(page, end * 0.6)
    wait_js(page, "() => document.getElementById('frame').complete")
    SCREENSHOT.parent.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(SCREENSHOT))

    # Play advances the one clock for every panel; pause holds it.
    scrub_to(page, 0)
    page.select_option("#speed", "1")
    page.click("#play")
    wait_js(page, "() => Number(document.getElementById('replay').dataset.events) > 5")
    page.click("#play")
    held = shown(page)
    page.wait_for_timeout(400)
    assert shown(page) == held
    assert 5 < held["events"] < len(log["events"]), "paused part-way through"
    assert page.inner_text("#play") == "Play"

    # Each claim and verdict is a mark on the timeline; a mark takes the replay to its moment.
    t0 = next(e for e in log["events"] if e["kind"] != "trial_created")["t_ns"]
    marked = [e for e in log["events"] if e["kind"] in ("target_claimed", "target_confirmed", "target_rejected")]
    assert len(marked) >= 6, "three claims and their verdicts"
    assert page.locator("#timeline-marks option").count() == len(marked) == page.locator("#marks button").count()
    second = marked[3]
    assert page.locator("#marks button").nth(3).inner_text().endswith("target 2 confirmed")
    page.locator("#marks button").nth(3).click()
    at = max(0.0, (second["t_ns"] - t0) / 1e6)
    assert shown(page) == expected_at(log, at)
    assert page.is_hidden("#overhead-card"), "a simulator trial has no overhead camera"
    page.close()


def test_replays_are_for_experimenters_only(server, browser):
    running, trial_id = server
    anonymous = browser.new_page()
    anonymous.goto(running.url + "/leaderboard")
    assert "demo team 1" in anonymous.inner_text("#leaderboard")
    assert anonymous.locator("a.replays").count() == 0
    anonymous.goto(running.url + f"/experimenter/trials/{trial_id}/replay")
    assert anonymous.url == running.url + "/", "replays are behind the experimenter's login"
    anonymous.close()

    page = browser.new_page()
    log_in(page, running.url)
    page.goto(running.url + "/leaderboard")
    page.locator("a.replays").first.click()
    page.locator(f"#replays a[href='/experimenter/trials/{trial_id}/replay']").click()
    page.wait_for_selector("#replay[data-ready='1']")
    assert f"trial {trial_id}" in page.inner_text("h1")
    page.close()

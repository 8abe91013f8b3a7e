"""What the browser tests share: where screenshots go, the maze's size, the experimenter's page,
and the checks every page passes."""

from __future__ import annotations

from pathlib import Path

from bench.live import REPO

# Debian's chromium, headless: never a browser Playwright downloads.
CHROMIUM = Path("/usr/bin/chromium")
FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]

ARTIFACTS = REPO / "test-artifacts"
W_M, H_M = 2.4638, 2.0574


def experimenter(browser, server, **context):
    page = browser.new_context(**context).new_page()
    page.goto(server.url + "/")
    page.fill("input[name=name]", "eve")
    page.fill("input[name=password]", "correct horse")
    page.click("#login")
    page.wait_for_url(server.url + "/experimenter")
    return page


def page_checks(page, name: str) -> None:
    """axe-core finds no serious or critical violation; nothing scrolls sideways at 390 px; no
    image is a broken placeholder."""
    from axe_playwright_python.sync_playwright import Axe

    page.wait_for_load_state("load")
    page.wait_for_timeout(300)  # the page scripts draw and fetch once
    violations = [v for v in Axe().run(page).response["violations"] if v["impact"] in ("serious", "critical")]
    assert not violations, (name, [(v["id"], [n["target"] for n in v["nodes"]][:3]) for v in violations])
    width = page.evaluate("() => [document.documentElement.scrollWidth, window.innerWidth]")
    assert width[0] <= width[1], (name, width)
    broken = page.evaluate("""() => [...document.images].filter(i => !i.hidden && i.getClientRects().length
        && !(i.complete && i.naturalWidth > 0)).map(i => i.id)""")
    assert not broken, (name, broken)

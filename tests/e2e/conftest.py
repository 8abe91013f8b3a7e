"""The browser every e2e test drives: Debian's chromium, headless, through Playwright (never a
browser Playwright downloads); the tests skip, saying why, where it is not installed."""

from __future__ import annotations

import pytest

from tests.e2e.pages import CHROMIUM, FLAGS


@pytest.fixture(scope="module")
def browser():
    if not CHROMIUM.exists():
        pytest.skip(f"{CHROMIUM} not found: install Debian's chromium to run the browser tests")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=str(CHROMIUM), args=FLAGS, headless=True)
        yield browser
        browser.close()

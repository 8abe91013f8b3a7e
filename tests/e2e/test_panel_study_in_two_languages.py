"""A whole panel study in headless Chromium, once in English and once in German: four strangers
arrive through the panel's links. Ann leaves the lobby (the next arrival is not paired with her);
Bob and Cat are paired and play; Bob answers the questionnaire and finishes the plan; Cat
withdraws; Dan never gets a partner. Each who ends gets the code of their outcome and lands on the
panel's completion address; the experimenter's export has the four rows
with those outcomes and the minutes to pay, and the answers are in the export and the report; a
participant downloads their own data; the purge deletes the personal data once the study has been
closed the set days (time faked by the study's closing date)."""

from __future__ import annotations

import csv
import json
from datetime import UTC, datetime, timedelta

import pytest
from sqlalchemy import select
from typer.testing import CliRunner

from app.cli import root
from app.db.models import Trial
from app.i18n import Language
from app.study.config import StudyFiles
from tests.app.test_study_own_data import personal, purge_cli
from tests.app.test_study_panel import PROLIFIC, backdate, stored
from tests.app.test_study_paths import study
from tests.e2e.test_study_in_browser import play_through
from tests.e2e.test_study_in_german import in_german
from tests.e2e.test_study_in_german import study as german_study

pytestmark = [pytest.mark.browser, pytest.mark.slow]
LANDED = "https://app.prolific.com/submissions/complete?cc={code}"
# Codes of digits: a word in them would read as English on the German pages.
DONE, CODES = "7000", {"partial": "7001", "no_partner": "7002", "withdrew": "7003", "screened_out": "7004"}


@pytest.mark.parametrize("language", [Language.en, Language.de])
def test_a_whole_panel_study_in_each_language(browser, server, tmp_path, language):
    plan = {
        "practice_maze": None,
        "trials_per_participant": 1,
        # The default: with 3 s, a lobby page's ask delayed on a loaded machine (it asks each 1-2 s)
        # counted Bob as gone when Cat arrived, and twice in a day they were not paired in 30 s. Ann
        # leaves by her button, so nothing here waits on the window.
        "lobby_presence_s": 10.0,
        "completion_code": DONE,
        "outcome_codes": CODES,
        "panel": {"completion_url": PROLIFIC},
        "language": language,
        "purge_after_days": 30,
    }
    if language == Language.de:  # the lab's own words, in the study's language
        plan |= german_study().model_dump(include={"title", "consent", "instructions", "questionnaire"})
    files = StudyFiles.of(server.settings.data_dir)
    files.save(study("pilot", **plan))
    landed: list[str] = []

    def speaks(page, name: str) -> None:
        if language == Language.de:
            in_german(page, name)
        else:
            assert page.get_attribute("html", "lang") == "en", name

    def arrive(pid: str, session: str, real_name: str):
        context = browser.new_context()
        context.route(
            "https://app.prolific.com/**",
            lambda route: (landed.append(route.request.url), route.fulfill(status=200, body="<p>submitted</p>")),
        )
        page = context.new_page()
        page.goto(f"{server.url}/study/pilot?PROLIFIC_PID={pid}&STUDY_ID=ST-77&SESSION_ID={session}")
        assert page.url == f"{server.url}/study/pilot", "the panel's identifiers are gone from the address bar"
        speaks(page, "consent")
        page.click("#agree")
        code = page.inner_text("#participant-code")
        page.fill("#real-name", real_name)
        page.click("#continue")
        page.click("#to-lobby")
        page.wait_for_url("**/study/pilot/lobby")
        speaks(page, "lobby")
        return page, code

    def lands(page, code: str) -> None:
        assert page.inner_text("#completion-code") == code
        speaks(page, f"the end page with {code}")
        page.click("#completion-link")
        page.wait_for_url("https://app.prolific.com/**")
        assert LANDED.format(code=code) in landed, landed

    ann, ann_code = arrive("PID-ANN", "SE-1", "Ann Real")
    ann.click("#leave")  # Ann leaves the lobby: she is not paired with the next arrival
    ann.wait_for_url("**/study/pilot/me")
    bob, bob_code = arrive("PID-BOB", "SE-2", "Bob Real")
    cat, cat_code = arrive("PID-CAT", "SE-3", "Cat Real")
    for page in (bob, cat):
        page.wait_for_url("**/play/**", timeout=30_000)
        page.wait_for_selector("#status[data-phase]")
        speaks(page, "the seat")
    with server.services.db() as db:
        trial = db.scalars(select(Trial).where(Trial.study == "pilot")).one()
        names = {stored(server, c).participant_id: c for c in (bob_code, cat_code)}
    assert {names.get(trial.commander_id), names.get(trial.driver_id)} == {bob_code, cat_code}
    play_through(server.services, trial.id, (bob, cat))  # localized, the three targets found

    bob.click("#after-trial:not([hidden]) #continue", timeout=30_000)
    bob.wait_for_url("**/questionnaire")
    speaks(bob, "questionnaire")
    for rating in bob.locator("fieldset[data-question]:has(input[value='4'])").all():
        rating.locator("input[value='4']").check()
    bob.fill("textarea", "Bob's own words")
    bob.click("#send-answers")
    bob.wait_for_selector("#answers-saved")
    bob.click("#finish")  # the plan's one trial is played: no confirming
    lands(bob, DONE)

    cat.goto(server.url + "/study/pilot/me")
    cat.click("#withdraw-from-study summary")
    cat.check("#withdraw-confirm")
    cat.click("#withdraw")
    lands(cat, CODES["withdrew"])

    dan, dan_code = arrive("PID-DAN", "SE-4", "Dan Real")  # Dan waits alone past the lobby's time
    for _ in range(300):  # his page's first ask puts him in the lobby (at most 30 s)
        if stored(server, dan_code).lobby_since is not None:
            break
        dan.wait_for_timeout(100)
    backdate(server, dan_code, waiting_min=11, in_study_min=15)
    dan.wait_for_url("**/study/pilot/done", timeout=30_000)
    lands(dan, CODES["no_partner"])

    mine = bob.context.request.get(server.url + "/study/pilot/me/data.json")  # Bob's own data
    assert mine.status == 200 and "Bob's own words" in mine.text() and ann_code not in mine.text()

    env = {"ROBOTSLANG_DATA_DIR": str(server.settings.data_dir), "ROBOTSLANG_SECRET_KEY": "test-secret"}
    out = tmp_path / "export"
    made = CliRunner().invoke(
        root, ["export", "all", "--study", "pilot", "--include-aborted", "--format", "ndh", "--out", str(out)], env=env
    )
    assert made.exit_code == 0, made.output
    with (out / "participants.csv").open() as f:
        rows = {r["participant"]: r for r in csv.DictReader(f)}
    assert {c: (r["outcome"], r["completion_code"], r["panel_participant"]) for c, r in rows.items()} == {
        ann_code: ("", "", "PID-ANN"),  # she left the lobby and has not come back
        bob_code: ("completed", DONE, "PID-BOB"),
        cat_code: ("withdrew", CODES["withdrew"], "PID-CAT"),
        dan_code: ("no_partner", CODES["no_partner"], "PID-DAN"),
    }
    assert float(rows[dan_code]["minutes_in_lobby"]) >= 11.0 and float(rows[dan_code]["minutes_in_study"]) >= 15.0
    answered = json.loads((out / "questionnaires.json").read_text())
    assert "Bob's own words" in json.dumps(answered)
    report = tmp_path / "report"
    made = CliRunner().invoke(root, ["report", "study", "--study", "pilot", "--out", str(report)], env=env)
    assert made.exit_code == 0, made.output
    assert json.loads((report / "study.json").read_text())["questionnaire"]["answers"] == 1

    files.save(files.load("pilot").model_copy(update={"closed_at": datetime.now(UTC) - timedelta(days=31)}))
    assert "personal data of" in purge_cli(server, "--study", "pilot")
    assert all(value is None for row in personal(server) for value in row), "names, panel ids and free text gone"

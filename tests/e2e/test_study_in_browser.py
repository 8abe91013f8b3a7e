"""A study in headless Chromium: four strangers arrive at different times through the study link,
consent, give a code (one a real name), wait in the lobby and are paired by the server; one leaves
the lobby and is paired on coming back; one team plays its trial to the end, the other's is stopped
by the experimenter; they answer the questionnaires and get the completion code; the played trial,
excluded, leaves the leaderboard and the exports; a participant withdraws and their name is gone
from the database while their events remain. Newcomers play a practice trial first (the bundled
maze, set aside from scores), then the study's trials. A lobby over its rate says to wait."""

from __future__ import annotations

import pytest
from sqlalchemy import select, text
from typer.testing import CliRunner

from app.cli import root
from app.db.models import Participant, StudyEvent, Trial
from app.security import Seat
from app.study.config import StudyFiles, template
from tests.app.live import experimenter_client, wait_js
from tests.e2e.pages import ARTIFACTS, drive_page_to_target, experimenter, page_checks

pytestmark = [pytest.mark.browser, pytest.mark.slow]
REAL_NAME = "Ada Quist"


def arrive(browser, server, real_name: str = "", checks: bool = False, opens_seats: bool = True):
    context = browser.new_context(viewport={"width": 390, "height": 800})
    if not opens_seats:  # a participant whose browser never loads the seat page it is sent to
        context.route("**/play/**", lambda route: route.abort())
    page = context.new_page()
    page.goto(server.url + "/study/pilot")
    if checks:
        page_checks(page, "study consent")
    page.click("#agree")
    if checks:
        page_checks(page, "study code")
    code = page.inner_text("#participant-code")
    page.fill("#real-name", real_name)
    page.click("#continue")
    if checks:
        page_checks(page, "study instructions")
    page.click("#to-lobby")
    page.wait_for_url("**/study/pilot/lobby")
    if checks:
        page_checks(page, "study lobby")
    return page, code


def lobby_says(page, words: str) -> None:
    wait_js(page, f"() => document.getElementById('lobby-status').textContent.includes({words!r})")


def go_on(page) -> None:
    """The seat page's "Continue", shown once the trial is over."""
    page.click("#after-trial:not([hidden]) #continue", timeout=30_000)


def questionnaire_and_code(page, comment: str) -> None:
    go_on(page)  # from the seat page of the trial just over to its questionnaire
    page.wait_for_url("**/questionnaire")
    page_checks(page, "study questionnaire")
    page.check("fieldset[data-question=difficulty] input[value='4']")
    page.check("fieldset[data-question=partner] input[value='5']")
    page.fill("textarea[name=comments]", comment)
    page.click("#send-answers")
    page.wait_for_selector("#my-trials >> text=answered")
    page.click("#finish")
    assert page.inner_text("#completion-code") == "DONE-PILOT"
    page_checks(page, "study done")


def play_through(services, trial_id: int, pages) -> None:
    """Of the participants' seat pages, the two of `trial_id` play it: the Commander marks the
    robot on the map, the Driver drives to each target and claims it, the Commander confirms."""
    seats = {services.seats.verify(page.url.rsplit("/play/", 1)[1]): page for page in pages}
    commander, driver = (seats[Seat(trial_id, role)] for role in ("commander", "driver"))
    commander.wait_for_selector("#status[data-phase=localizing]")
    driver.fill("#chat-input", "I see a blue wall on my left")
    driver.press("#chat-input", "Enter")
    commander.click("#map")  # "the robot is here"
    driver.wait_for_selector("#status[data-phase=navigating]")
    for _ in range(3):
        drive_page_to_target(services, trial_id, driver)
        driver.click("#found")
        commander.click("#claim:not([hidden]) #confirm")
    for page in (commander, driver):
        page.wait_for_selector("#status[data-phase=finished]")


def test_a_whole_study_with_four_strangers(browser, server, tmp_path):
    StudyFiles(server.settings.data_dir / "studies").save(  # one planned trial after the practice
        template("pilot").model_copy(update={"lobby_presence_s": 3.0, "trials_per_participant": 1})
    )
    eve = experimenter_client(server.services, server.url)

    ada, ada_code = arrive(browser, server, REAL_NAME, checks=True)
    lobby_says(ada, "only one waiting")
    ben, _ = arrive(browser, server)
    for page in (ada, ben):
        page.wait_for_url("**/play/**", timeout=30_000)
    cy, cy_code = arrive(browser, server)
    lobby_says(cy, "only one waiting")
    # The experimenter's study page shows the lobby live; "Choose" puts a code in the pair-by-hand form.
    study_page = experimenter(browser, server)
    study_page.goto(server.url + "/experimenter/studies/pilot")
    wait_js(study_page, f"() => !!document.querySelector('#lobby-live tr[data-code=\"{cy_code}\"]')")
    page_checks(study_page, "study page, the lobby live")
    study_page.screenshot(path=str(ARTIFACTS / "study-lobby-live.png"), full_page=True)
    # Pressed for longer than the table's 2 s refresh, as a hesitant hand does: the press still counts.
    study_page.hover(f'#lobby-live tr[data-code="{cy_code}"] button')
    study_page.mouse.down()
    study_page.wait_for_timeout(2500)
    study_page.mouse.up()
    assert study_page.input_value("#pair-by-hand [name=a]") == cy_code
    cy_browser = cy.context
    cy.close()  # Cy's tab closes in the lobby
    ben.wait_for_timeout(3500)  # past the study's lobby_presence_s
    dee, _ = arrive(browser, server)
    lobby_says(dee, "only one waiting")  # Cy, gone, is neither counted nor paired
    cy = cy_browser.new_page()  # Cy comes back: the study link brings the same participant back
    cy.goto(server.url + "/study/pilot")
    cy.click("#to-lobby")
    for page in (cy, dee):
        page.wait_for_url("**/play/**", timeout=30_000)

    def study_trials():
        with server.services.db() as db:
            return list(db.scalars(select(Trial).where(Trial.study == "pilot").order_by(Trial.id)))

    practice = study_trials()
    assert [(t.maze, t.excluded_reason) for t in practice] == [("gen-000", "study practice: not scored")] * 2
    for t in practice:  # the practice ends (here by the experimenter); everyone goes back to the lobby
        assert eve.post(f"/experimenter/trials/{t.id}/abort").status_code == 200
    for page in (ada, ben, cy, dee):
        go_on(page)  # the practice has no questionnaire: on to the lobby
    for page in (ada, ben, cy, dee):
        page.wait_for_url("**/play/**", timeout=30_000)
    trials = study_trials()[2:]
    assert len(trials) == 2 and {t.excluded_reason for t in trials} == {None}
    assert "gen-000" not in {t.maze for t in trials}
    for page in (ada, ben, cy, dee):  # the live seat pages (Ben's or Cy's may be Ada's partner's)
        page.wait_for_load_state("load")
        assert REAL_NAME not in page.content()
    play_through(server.services, trials[0].id, (ada, ben, cy, dee))  # one team plays its trial to the end
    assert eve.post(f"/experimenter/trials/{trials[1].id}/abort").status_code == 200  # the other is stopped
    board = browser.new_context().new_page()
    board.goto(server.url + "/leaderboard?study=pilot")
    assert board.locator("#leaderboard td.team").count() == 1
    questionnaire_and_code(ada, f"I am {REAL_NAME}; the mug was hard to see")
    for page in (ben, cy, dee):
        questionnaire_and_code(page, "fine")

    assert eve.post(f"/experimenter/trials/{trials[0].id}/exclude", data={"reason": "pilot trouble"}).status_code == 200
    board.reload()
    assert board.locator("#leaderboard td.team").count() == 0, "the excluded trial left the leaderboard"
    env = {"ROBOTSLANG_DATA_DIR": str(server.settings.data_dir), "ROBOTSLANG_SECRET_KEY": "test-secret"}
    out = tmp_path / "mcap"
    result = CliRunner().invoke(
        root, ["export", "all", "--include-aborted", "--format", "mcap", "--out", str(out)], env=env
    )
    assert result.exit_code == 0, result.output
    assert sorted(p.name for p in out.glob("*.mcap")) == [f"trial-{trials[1].id}.mcap"], (
        "the excluded trial is left out"
    )

    ada.goto(server.url + "/study/pilot/me")
    ada.click("#my-study summary")
    ada.check("#withdraw-confirm")
    ada.click("#withdraw")
    ada.wait_for_selector("#withdrawn")
    with server.services.engine.connect() as conn:
        tables = [r[0] for r in conn.execute(text("select name from sqlite_master where type='table'"))]
        everything = "\n".join(str(row) for t in tables for row in conn.execute(text(f'select * from "{t}"')))
    assert REAL_NAME not in everything
    with server.services.db() as db:
        ada_id = db.scalar(select(Participant.id).where(Participant.name == ada_code))
        kinds = [e.kind for e in db.scalars(select(StudyEvent).where(StudyEvent.participant_id == ada_id))]
    assert ada_code in everything and kinds[0] == "consented" and kinds[-1] == "withdrawn"


def test_a_partner_who_never_comes_sends_the_other_back_to_the_lobby(browser, server):
    plan = {"practice_maze": None, "join_timeout_s": 6.0}  # Ann's page opens her seat well within it
    StudyFiles(server.settings.data_dir / "studies").save(template("pilot").model_copy(update=plan))
    ann, _ = arrive(browser, server)
    bob, _ = arrive(browser, server, opens_seats=False)
    ann.wait_for_url("**/play/**", timeout=30_000)
    wait_js(ann, "() => !document.getElementById('after-trial').hidden")
    assert "never joined" in ann.inner_text("#announce")
    ann.screenshot(path=str(ARTIFACTS / "study-partner-never-came.png"))
    ann.wait_for_url("**/study/pilot/lobby", timeout=30_000)  # on its own, with nothing to rate
    lobby_says(ann, "only one waiting")
    bob.context.close()


@pytest.mark.settings(study_lobby_limit_per_address="1/minute")
def test_a_lobby_over_its_rate_says_to_wait_and_pairs_no_one(browser, server):
    StudyFiles(server.settings.data_dir / "studies").save(template("pilot"))
    ann, _ = arrive(browser, server)
    lobby_says(ann, "You are the only one waiting")
    bob, _ = arrive(browser, server)  # the same address: its second entry into the lobby this minute
    lobby_says(bob, "Please wait: more people are joining the lobby than it takes at once")
    page_checks(bob, "study lobby over its rate")
    ann.wait_for_timeout(1500)  # Ann's page asked again meanwhile: Bob was not let in to be paired
    assert "You are the only one waiting" in ann.inner_text("#lobby-status")

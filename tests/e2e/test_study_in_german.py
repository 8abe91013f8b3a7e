"""A study in German, in headless Chromium: every page a participant sees (consent, declining,
their code, the instructions, the lobby, the Commander's and the Driver's seats as the trial runs
and ends, the closed join link, the questionnaire, their page, finishing early, the end and
withdrawal pages, a full and a closed study, the error pages) is in German, the scripts' words
too: no word of the English messages is left on any of them; so are an LDH study's pages."""

from __future__ import annotations

import re
from datetime import UTC, datetime

import pytest

from app.db.models import Experimenter
from app.i18n import Language, catalog
from app.security import StudyTokens, hash_password
from app.study.config import Consent, Question, QuestionKind, RoleInstructions, StudyFiles, StudyOutcome, template
from tests.app.live import platform_settings, wait_js
from tests.e2e.pages import mark_on_map, page_checks

pytestmark = [pytest.mark.browser, pytest.mark.slow]

WORD = re.compile(r"[^\W\d_]+")
PLACEHOLDER = re.compile(r"\{\w+\}|%\(\w+\)[sd]")
CODE = re.compile(r"\bP-[A-Z2-9]+\b")  # a participant's code: random letters ("P-A7KX" is no English "a")


def words(text: str) -> set[str]:
    return {w.lower() for w in WORD.findall(PLACEHOLDER.sub(" ", text))}


def english_only() -> set[str]:
    """The words of the English messages that no German one uses ("Chat", "x" and "Sie" are both)."""
    english, german = set(), set()
    for m in catalog(Language.de):
        for text in (m.id,) if isinstance(m.id, str) else m.id:
            english |= words(text)
        for text in (m.string,) if isinstance(m.string, str) else m.string:
            german |= words(text)
    return english - german


ENGLISH = english_only()
# What a participant sees, shown or not yet: the page's text, its title and the words in its attributes.
SEEN = """() => [document.title, document.body.textContent,
  ...[...document.querySelectorAll('[aria-label], [placeholder], [alt], [title]')].flatMap(
    (e) => ['aria-label', 'placeholder', 'alt', 'title'].map((a) => e.getAttribute(a) || ''))].join(' ')"""


def in_german(page, name: str) -> None:
    page.wait_for_load_state("load")
    assert page.get_attribute("html", "lang") == "de", name
    left = words(CODE.sub(" ", page.evaluate(SEEN))) & ENGLISH
    assert not left, (name, sorted(left))


def study():
    return template("roboter").model_copy(
        update={
            "language": Language.de,
            "title": "Roboter lotsen",
            "consent": Consent(version="1", text="Sie chatten mit einer anderen Person und lotsen einen Roboter."),
            "instructions": RoleInstructions(
                commander="Sie sehen die Karte und lotsen.", driver="Sie sehen das Kamerabild und fahren."
            ),
            "questionnaire": [
                Question(id="schwer", kind=QuestionKind.difficulty, prompt="Wie schwer war es? (1 leicht – 5 schwer)"),
                Question(id="sonst", kind=QuestionKind.free_text, prompt="Möchten Sie uns noch etwas sagen?"),
            ],
            "practice_maze": None,
            "trials_per_participant": 2,
            "max_participants": 2,
            "completion_code": "FERTIG",
            "outcome_codes": {StudyOutcome.partial: "TEIL", StudyOutcome.withdrew: "ZURUECK"},
        }
    )


def arrive(browser, server):
    page = browser.new_context(viewport={"width": 1200, "height": 900}).new_page()
    page.goto(server.url + "/study/roboter")
    in_german(page, "consent")
    page.click("#agree")
    page.wait_for_url("**/code")  # each page checked once it is there, not while the last one goes
    in_german(page, "code")
    page.click("#continue")
    page.wait_for_url("**/instructions")
    in_german(page, "instructions")
    page.click("#to-lobby")
    page.wait_for_url("**/lobby")
    return page


@pytest.mark.settings(grace_period_s=3.0)  # the Driver's page closes: the trial ends that soon after
def test_every_participant_page_of_a_german_study_is_in_german(browser, server):
    files = StudyFiles.of(server.settings.data_dir)
    files.save(study())
    files.save(
        template("vorbei").model_copy(update={"language": Language.de, "closed_at": datetime(2026, 1, 1, tzinfo=UTC)})
    )

    cy = browser.new_context().new_page()  # Cy declines
    cy.goto(server.url + "/study/roboter")
    cy.click("#decline")
    cy.wait_for_selector("#declined")
    in_german(cy, "declined")
    cy.goto(server.url + "/study/roboter/me")  # and has no pass: the error page
    assert cy.locator("#error-page[data-status='403']").count() == 1
    in_german(cy, "403")
    cy.goto(server.url + "/study/vorbei")
    in_german(cy, "closed")

    ann = arrive(browser, server)
    wait_js(ann, "() => document.getElementById('lobby').dataset.waiting === '1'")
    in_german(ann, "lobby, waiting alone")
    page_checks(ann, "lobby in German")
    ben = arrive(browser, server)
    cy.goto(server.url + "/study/roboter")  # both places taken
    in_german(cy, "full")

    for page in (ann, ben):
        page.wait_for_url("**/play/**", timeout=30_000)
        page.wait_for_selector("#status[data-phase=localizing]")
    role = {page: page.get_attribute("#seat", "data-role") for page in (ann, ben)}
    commander, driver = sorted((ann, ben), key=lambda p: role[p] != "commander")
    commander.click("#map-text summary")  # the map in words, as a screen reader has it
    commander.focus("#map")
    commander.keyboard.press("ArrowUp")  # the keyboard cursor says where it is
    in_german(commander, "Commander, localizing")
    in_german(driver, "Driver, localizing")
    mark_on_map(commander)
    driver.wait_for_selector("#status[data-phase=navigating]")
    driver.click("#forward")
    driver.wait_for_selector("#camera[aria-busy=false]")
    driver.click("#found")  # a claim: the Commander judges it
    commander.wait_for_selector("#claim:not([hidden])")
    in_german(commander, "Commander, a claim to judge")
    in_german(driver, "Driver, claimed")
    page_checks(commander, "Commander in German")
    commander.click("#reject")
    wait_js(driver, "() => document.getElementById('move-note').textContent !== ''")
    in_german(driver, "Driver, claim rejected")
    seat = driver.url
    driver.close()  # the Driver's page goes; past the grace period the trial ends
    wait_js(
        commander,
        "() => document.getElementById('status').dataset.phase === 'navigating'"
        " && document.body.textContent.includes('Pause')",
    )
    in_german(commander, "Commander, the Driver away")
    wait_js(commander, "() => !document.getElementById('after-trial').hidden")
    in_german(commander, "Commander, the trial ended early")

    commander.click("#continue")
    commander.wait_for_url("**/questionnaire")
    in_german(commander, "questionnaire")
    questionnaire = commander.url
    commander.check("fieldset[data-question=schwer] input[value='3']")
    commander.click("#send-answers")
    commander.wait_for_url("**/me?saved=true")
    in_german(commander, "my page")
    commander.goto(questionnaire)  # answered already: 404
    assert commander.locator("#error-page[data-status='404']").count() == 1
    in_german(commander, "404")
    commander.goto(server.url + "/study/roboter/me")
    commander.click("#finish")
    commander.wait_for_selector("#finish-confirm")
    in_german(commander, "finish early?")
    commander.click("#confirm-finish")
    assert commander.inner_text("#completion-code") == "TEIL"
    in_german(commander, "done, partial")

    driver = driver.context.new_page()  # the Driver comes back to the link
    driver.goto(seat)
    in_german(driver, "the closed join link")
    driver.click("#continue")
    driver.wait_for_url("**/questionnaire")
    driver.goto(server.url + "/study/roboter/me")
    driver.click("#my-study summary")
    driver.check("#withdraw-confirm")
    driver.click("#withdraw")
    assert driver.inner_text("#completion-code") == "ZURUECK"
    in_german(driver, "withdrawn")


# The dialog an LDH participant reads is the study's material, in the language it was typed: its
# speakers are the page's words, what they said is not.
WITHOUT_WHAT_WAS_SAID = """() => document.querySelectorAll('#messages li').forEach(
  (li) => [...li.childNodes].filter((n) => n.nodeType === Node.TEXT_NODE).forEach((n) => n.remove()))"""


def test_an_ldh_study_in_german_is_in_german(browser, start_server, tmp_path, benchmark_path):
    server = start_server(platform_settings(tmp_path / "ldh", benchmark=benchmark_path))
    with server.services.db.begin() as db:
        db.add(Experimenter(name="eve", password_hash=hash_password("correct horse")))
    studies = server.services.studies
    study = studies.create(1, "wo", str(benchmark_path), "val_seen", "prefix", 1, Language.de)
    token = StudyTokens(server.settings.signing_key()).issue(study, studies.invite(study, "ann"))
    page = browser.new_context(viewport={"width": 1200, "height": 900}).new_page()
    page.goto(f"{server.url}/ldh/{token}")
    page.focus("#map")
    page.keyboard.press("ArrowUp")  # the keyboard cursor says where it is
    page.evaluate(WITHOUT_WHAT_WAS_SAID)
    in_german(page, "LDH, an instance to answer")
    page_checks(page, "LDH in German")
    page.keyboard.press("Enter")
    page.click("#submit")
    page.wait_for_selector("#ldh-done")
    in_german(page, "LDH, done")

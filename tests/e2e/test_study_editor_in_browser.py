"""A study set up without JSON, in headless Chromium: the experimenter creates it, copies the
participants' whole link with a button, sets it up in the form (the JSON stays one click away);
and the dashboard's live refresh keeps a trial's practice and exclusion marks."""

from __future__ import annotations

import pytest

from app.study.config import StudyFiles
from tests.app.live import add_experimenter
from tests.e2e.pages import ARTIFACTS, experimenter, page_checks

pytestmark = [pytest.mark.browser]


def test_a_study_is_set_up_in_its_form_and_its_link_copied(browser, server):
    add_experimenter(server)
    admin = experimenter(browser, server, viewport={"width": 1200, "height": 900})
    admin.context.grant_permissions(["clipboard-read", "clipboard-write"], origin=server.url)
    admin.goto(server.url + "/experimenter/studies")
    admin.fill("#new-study input[name=name]", "pilot")
    admin.click("#new-study button")
    admin.wait_for_url("**/experimenter/studies/pilot")
    assert admin.input_value("#study-url") == f"{server.url}/study/pilot"
    admin.click("#copy-link")
    admin.wait_for_selector("#copied >> text=Copied.")
    assert admin.evaluate("navigator.clipboard.readText()") == f"{server.url}/study/pilot"
    assert admin.is_hidden("#config-json"), "the JSON is there for power users, folded away"
    page_checks(admin, "study editor")

    admin.fill("input[name=title]", "Robots in mazes")
    admin.fill("input[name=trials_per_participant]", "3")
    admin.fill("textarea[name=maze_pool]", "gen-001\ngen-002")
    admin.fill("input[name='questionnaire.3.id']", "fun")
    admin.select_option("select[name='questionnaire.3.kind']", "difficulty")
    admin.fill("input[name='questionnaire.3.prompt']", "How much fun was it? (1-5)")
    admin.fill("input[name='outcome_codes.no_partner']", "WAITED-1")
    admin.screenshot(path=str(ARTIFACTS / "study-editor-form.png"), full_page=True)
    admin.click("#save-study")
    admin.wait_for_selector("#saved >> text=Saved as version 2")
    study = StudyFiles.of(server.settings.data_dir).load("pilot")
    assert (study.title, study.trials_per_participant, study.maze_pool) == (
        "Robots in mazes",
        3,
        ["gen-001", "gen-002"],
    )
    assert study.questionnaire[-1].id == "fun" and study.outcome_codes == {"no_partner": "WAITED-1"}
    # The saved study comes back in the form: one maze a line, the new item, an empty row to add.
    assert admin.input_value("textarea[name=maze_pool]") == "gen-001\ngen-002"
    assert admin.input_value("input[name='questionnaire.3.id']") == "fun"
    assert admin.input_value("input[name='questionnaire.4.id']") == ""

    admin.fill("input[name=join_timeout_s]", "-5")
    admin.click("#save-study")
    admin.wait_for_selector("[role=alert] >> text=join_timeout_s")
    assert admin.input_value("input[name=join_timeout_s]") == "-5", "the typed value is kept to fix"
    assert StudyFiles.of(server.settings.data_dir).load("pilot").version == 2
    page_checks(admin, "study editor, a value refused")
    admin.context.close()


def test_the_dashboards_live_refresh_keeps_a_trials_marks(browser, server, trials):
    from app.trial.lifecycle import exclude_trial

    add_experimenter(server)
    trial = trials.new(team="Marked")
    admin = experimenter(browser, server)
    admin.once("dialog", lambda d: d.accept())
    admin.click(f"tr[data-trial='{trial.id}'] form.control-abort button")
    admin.locator(f"tr[data-trial='{trial.id}'] .phase", has_text="aborted").wait_for()
    with server.services.db.begin() as db:
        exclude_trial(db, trial.id, "the rover fell over")
    admin.reload()
    row = admin.locator(f"tr[data-trial='{trial.id}']")
    admin.wait_for_timeout(2500)  # two refreshes
    assert row.locator(".excluded").inner_text() == "(excluded: the rover fell over)"
    assert row.locator(".phase").inner_text() == "aborted"
    admin.context.close()

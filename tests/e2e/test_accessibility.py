"""Accessibility as a gate: every page the app serves (each route whose answer is a page, read
from the app's own OpenAPI description) is visited in headless Chromium with the content it
shows in use, as the person who opens it (a participant, an annotator, the experimenter, anyone
with a link), at a phone's width; axe-core finds no serious or critical violation on any. A route
added without a visit here fails the test, named. And the Commander's map in words, for a screen
reader, follows the mark."""

from __future__ import annotations

import re
from urllib.parse import urlsplit

import pytest
from sqlalchemy import update

from app.annotation.events import CutMarked, Submitted, Tagged
from app.db.models import AnnotationAssignment, Experimenter, Trial
from app.export.ndh import write_benchmark
from app.security import AccountRole, StudyTokens, hash_password
from app.study.config import StudyFiles, template
from tests.app.live import add_experimenter, wait_js
from tests.app.trial_log import maze_named, ndh_trial_record
from tests.e2e.pages import experimenter, log_in, page_checks

pytestmark = pytest.mark.browser
PHONE = {"viewport": {"width": 390, "height": 844}, "has_touch": True, "is_mobile": True}


def page_routes(app) -> set[str]:
    """The paths of every route that answers with a page (text/html), as the app describes them."""
    return {
        path
        for path, operations in app.openapi()["paths"].items()
        for operation in operations.values()
        if any("text/html" in answer.get("content", {}) for answer in operation["responses"].values())
    }


class Visits:
    """Each page checked, by the route it is the answer of."""

    def __init__(self, routes: set[str]) -> None:
        self.routes = routes
        self.patterns = {path: re.compile("^" + re.sub(r"\{[^}]+\}", "[^/]+", path) + "$") for path in routes}
        self.seen: set[str] = set()

    def check(self, page, name: str) -> None:
        page_checks(page, name)
        path = urlsplit(page.url).path
        self.seen |= {route for route, pattern in self.patterns.items() if pattern.match(path)}


def test_every_page_has_no_serious_or_critical_axe_violation(browser, server, trials):
    services, settings = server.services, server.settings
    visits = Visits(page_routes(server.app))
    add_experimenter(server)

    # What the pages show: a live trial (its seats open), one ended, a finished trial of study
    # "s1" two annotators disagree on, an LDH study of an export, and a participant study.
    names = services.mazes.names()
    live = trials.new(maze=names[0], team="Live")
    ended = trials.new(maze=names[1], team="Ended")
    annotated = trials.new(maze=names[2], team="Annotated").id
    with services.db.begin() as db:
        db.execute(update(Trial).where(Trial.id == annotated).values(phase="finished", study="s1", active_s=60.0))
        annotators = []
        for who in ("ann", "bob"):
            account = Experimenter(name=who, password_hash=hash_password("annotate well"), role=AccountRole.ANNOTATOR)
            db.add(account)
            db.flush()
            annotators.append(account.id)
            db.add(AnnotationAssignment(trial_id=live.id, annotator_id=account.id))
    for who, cut, tagged in zip(annotators, (1, 2), (True, False), strict=True):
        services.annotations.append(annotated, who, CutMarked(message=cut), 1)
        if tagged:
            services.annotations.append(annotated, who, Tagged(tag="needs_history", messages=[1]), 2)
        services.annotations.append(annotated, who, Submitted(), 3)
    export = maze_named("gen-900")
    summary = write_benchmark([(ndh_trial_record("1", export.name), export)], settings.data_dir / "export")
    split = next(s for s, n in summary.ldh.items() if n)
    ldh = services.studies.create(1, "ldh pilot", "export", split, "prefix")
    ldh_link = f"/ldh/{StudyTokens(settings.signing_key()).issue(ldh, services.studies.invite(ldh, 'ann'))}"
    StudyFiles(settings.data_dir / "studies").save(template("pilot"))

    # The seat pages of the live trial; the Commander marks the robot and both chat.
    commander, driver = (browser.new_context(**PHONE).new_page() for _ in range(2))
    commander.goto(live.play_url("commander"))
    driver.goto(live.play_url("driver"))
    for page in (commander, driver):
        page.wait_for_selector("#status[data-phase=localizing]")
    visits.check(commander, "Commander, localizing")
    driver.fill("#chat-input", "a red wall ahead")
    driver.press("#chat-input", "Enter")
    commander.tap("#map")
    driver.wait_for_selector("#status[data-phase=navigating]")
    visits.check(commander, "Commander, navigating")
    visits.check(driver, "Driver, navigating")

    anyone = browser.new_context(**PHONE).new_page()
    for name, path in [
        ("home", "/"),
        ("bad join link", "/join?link=nonsense"),
        ("bad seat link", "/play/nonsense"),
        ("leaderboard", "/leaderboard"),
        ("not found", "/no/such/page"),
        ("LDH study, first instance", ldh_link),
    ]:
        anyone.goto(server.url + path)
        visits.check(anyone, name)

    admin = experimenter(browser, server, **PHONE)
    admin.goto(f"{server.url}/experimenter/trials/{ended.id}")
    admin.once("dialog", lambda d: d.accept())
    admin.click("form.control-abort button")
    admin.wait_for_selector("#status[data-phase=aborted]")
    anyone.goto(ended.play_url("driver"))
    visits.check(anyone, "a seat link of an ended trial")
    for name, path in [
        ("dashboard", "/experimenter"),
        ("trial, live", f"/experimenter/trials/{live.id}"),
        ("trial, ended", f"/experimenter/trials/{ended.id}"),
        ("replays", "/experimenter/replays"),
        ("replay", f"/experimenter/trials/{ended.id}/replay"),
        ("annotation agreement, no study", "/experimenter/annotation"),
        ("annotation agreement", "/experimenter/annotation?study=s1"),
        ("LDH studies", "/experimenter/ldh"),
        ("LDH study", f"/experimenter/ldh/{ldh}"),
        ("studies", "/experimenter/studies"),
        ("study", "/experimenter/studies/pilot"),
    ]:
        admin.goto(server.url + path)
        visits.check(admin, name)

    annotator = log_in(browser, server, "ann", "annotate well", "/annotate", **PHONE)
    visits.check(annotator, "annotation queue")
    annotator.goto(f"{server.url}/annotate/trials/{live.id}")
    wait_js(annotator, "() => document.getElementById('replay').dataset.ready === '1'")
    visits.check(annotator, "annotating a trial")

    # A participant's way through the study, and one who declines, and one who withdraws.
    for choice in ("agree", "decline", "withdraw"):
        person = browser.new_context(**PHONE).new_page()
        person.goto(server.url + "/study/pilot")
        visits.check(person, "study consent")
        person.click("#decline" if choice == "decline" else "#agree")
        if choice == "decline":
            visits.check(person, "study declined")
            continue
        if choice == "withdraw":
            person.goto(server.url + "/study/pilot/me")
            person.click("#my-study summary")
            person.check("#withdraw-confirm")
            person.click("#withdraw")
            person.wait_for_selector("#withdrawn")
            visits.check(person, "study withdrawn")
            continue
        visits.check(person, "study code")
        person.click("#continue")
        visits.check(person, "study instructions")
        person.click("#to-lobby")
        person.wait_for_url("**/study/pilot/lobby")
        visits.check(person, "study lobby")
        person.goto(f"{server.url}/study/pilot/trials/{ended.id}/questionnaire")
        visits.check(person, "study questionnaire")
        person.goto(server.url + "/study/pilot/me")
        visits.check(person, "study, my page")
        person.click("#finish")
        visits.check(person, "study, finishing")  # with nothing played, nothing to finish yet
        # The experimenter screens them out: their way ends, and the end page gives its code.
        person.goto(server.url + "/study/pilot/me")
        code = person.inner_text("#participant-code")
        admin.goto(server.url + "/experimenter/studies/pilot")
        admin.fill("#screen-out input[name=code]", code)
        admin.click("#screen")
        person.goto(server.url + "/study/pilot/done")
        person.wait_for_url("**/study/pilot/done")
        visits.check(person, "study done")

    assert visits.routes - visits.seen == set(), "pages the app serves that no visit checked"


def test_the_commanders_map_in_words_names_the_walls_the_landmarks_and_the_mark_as_it_moves(browser, server, trial):
    services = server.services
    maze = services.mazes.names()[0]  # the `trial` fixture's, its targets mug, jar, paddle
    commander, driver = (browser.new_context().new_page() for _ in range(2))
    commander.goto(trial.play_url("commander"))
    driver.goto(trial.play_url("driver"))
    commander.wait_for_selector("#status[data-phase=localizing]")
    commander.click("#map-text summary")
    wait_js(commander, "() => document.querySelectorAll('#map-text-landmarks li').length === 3")

    walls = services.mazes.map_walls(maze)
    said = commander.locator("#map-text-walls li").all_inner_texts()
    assert len(said) == len(walls) > 3
    for wall, words in zip(walls, said, strict=True):
        assert words.startswith(f"{wall['colour']} wall"), words
        if wall["shape"] == "straight":
            (x0, y0), (x1, y1) = wall["from"], wall["to"]
            assert f"(x {x0:.2f}, y {y0:.2f}) to " in words and words.endswith(f"(x {x1:.2f}, y {y1:.2f})"), words
    landmarks = commander.locator("#map-text-landmarks li").all_inner_texts()
    for name, (x, y) in services.mazes.landmarks(maze).items():
        (words,) = [w for w in landmarks if w.startswith(name + " ")]
        assert f"(x {x:.2f}, y {y:.2f})" in words
        assert words.endswith("the next target") == (name == "mug"), words
    assert commander.inner_text("#map-text-mark") == "You have not marked the robot yet."
    page_checks(commander, "Commander, the map in words open, on a desktop")

    # Marked by keyboard from the centre (1.23, 1.03): 0.2 m east, 0.1 m north, turned to face north.
    commander.focus("#map")
    for key in ["ArrowRight"] * 4 + ["ArrowUp"] * 2 + ["["] * 2:
        commander.keyboard.press(key)
    commander.keyboard.press("Enter")
    wait_js(commander, "() => document.getElementById('map-text-mark').textContent.includes('facing north')")
    assert (
        commander.inner_text("#map-text-mark")
        == "Your mark of the robot: in the centre (x 1.43, y 1.13), facing north."
    )

    # The same link opened on a phone takes the seat and the mark from the server; a tap moves it.
    phone = browser.new_context(**PHONE).new_page()
    phone.goto(trial.play_url("commander"))
    phone.wait_for_selector("#status[data-phase=navigating]")
    wait_js(phone, "() => document.getElementById('map-text-mark').textContent.includes('facing north')")
    assert phone.text_content("#map-text-mark") == commander.text_content("#map-text-mark")
    box = phone.locator("#map").bounding_box()
    phone.tap("#map", position={"x": box["width"] * 0.1, "y": box["height"] * 0.9})
    wait_js(phone, "() => document.getElementById('map-text-mark').textContent.includes('south-west')")
    assert phone.text_content("#map-text-mark") == "Your mark of the robot: in the south-west (x 0.25, y 0.21)."
    for page in (commander, driver, phone):
        page.context.close()

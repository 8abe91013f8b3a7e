"""An LDH human study end to end in headless Chromium: the experimenter creates a study from
val_seen and invites two participants; each answers one instance at a time (by mouse with a
drag for the heading, and by keyboard) without ever seeing the truth until done; the
experimenter's tables and the CSV/JSON export hold every answer, scored by TD on the graph."""

from __future__ import annotations

import csv
import io
import math

import pytest

from app.db.models import Experimenter
from app.security import StudyTokens, hash_password
from sim.tasks.benchmark import Benchmark
from sim.tasks.ldh import LDHInstance, Variant
from sim.tasks.ldh_eval import MazeContext, score
from tests.e2e.pages import ARTIFACTS, H_M, W_M, experimenter, page_checks

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def server(start_module_server, benchmark_path):
    running = start_module_server(benchmark=benchmark_path)
    with running.services.db.begin() as db:
        db.add(Experimenter(name="eve", password_hash=hash_password("correct horse")))
    return running


def canvas_point(page, fx: float, fy: float) -> tuple[float, float]:
    box = page.locator("#map").bounding_box()
    return box["x"] + box["width"] * fx, box["y"] + box["height"] * fy


def answer_by_drag(page, fx: float, fy: float) -> None:
    """Press at (fx, fy) of the map and drag to the right: the robot faces +x (heading 0)."""
    x, y = canvas_point(page, fx, fy)
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x + 40, y, steps=4)
    page.mouse.up()
    page.click("#submit")


def answer_by_keyboard(page) -> None:
    """From the map's centre, three steps right and two up, turned once counter-clockwise."""
    page.focus("#map")
    for key in ["ArrowRight"] * 3 + ["ArrowUp"] * 2 + ["["]:
        page.keyboard.press(key)
    page.keyboard.press("Enter")
    page.click("#submit")


def truth_hidden(page, instances) -> None:
    text = page.content()
    for inst in instances:
        assert f"{inst['true_x']:.2f}" not in text and f"{inst['true_x']:.3f}" not in text


def test_a_study_from_creation_to_export(browser, server, benchmark_path):
    admin = experimenter(browser, server)
    admin.click("text=LDH studies")
    page_checks(admin, "ldh studies")
    admin.fill("#new-study input[name=name]", "pilot")
    assert admin.input_value("#new-study input[name=source]") == str(benchmark_path)
    admin.select_option("#new-study select[name=split]", "val_seen")
    admin.fill("#new-study input[name=limit]", "2")
    admin.click("#create-study")
    admin.wait_for_selector("#per-instance")
    study_url = admin.url
    for name in ("ann", "bob"):
        admin.fill("input[name=name]", name)
        admin.click("#invite")
        admin.wait_for_selector(f"tr[data-participant={name}]")
    page_checks(admin, "ldh study")
    links = {name: admin.get_attribute(f"tr[data-participant={name}] a.study-link", "href") for name in ("ann", "bob")}
    empty = admin.request.get(study_url + "/export.json").json()
    assert empty["study"]["n_instances"] == 2 and empty["answers"] == []
    hidden = [{"true_x": i.true_x} for i in server.services.studies.instances(empty["study"]["id"])]

    ann = browser.new_context().new_page()
    ann.goto(links["ann"])
    ann.wait_for_selector("#map")
    page_checks(ann, "ldh answer")
    assert "1 of 2" in ann.inner_text("h1") and ann.is_disabled("#submit")
    assert ann.locator("#messages li").count() >= 1  # the dialog is shown
    truth_hidden(ann, hidden)
    ARTIFACTS.mkdir(exist_ok=True)
    ann.screenshot(path=str(ARTIFACTS / "ldh-study-answer.png"), full_page=True)
    answer_by_drag(ann, 0.30, 0.40)
    ann.wait_for_selector("h1:has-text('2 of 2')")
    truth_hidden(ann, hidden)
    answer_by_keyboard(ann)
    ann.wait_for_selector("#ldh-done")
    page_checks(ann, "ldh done")

    bob = browser.new_context().new_page()
    bob.goto(links["bob"])
    answer_by_drag(bob, 0.70, 0.60)
    bob.wait_for_selector("h1:has-text('2 of 2')")
    bob.goto(links["bob"])  # a reload keeps their place and shows no truth
    assert "2 of 2" in bob.inner_text("h1")
    answer_by_drag(bob, 0.55, 0.25)
    bob.wait_for_selector("#ldh-done")

    export = admin.request.get(study_url + "/export.json").json()
    answers = export["answers"]
    assert [(a["participant"], a["position"]) for a in answers] == [("ann", 0), ("ann", 1), ("bob", 0), ("bob", 1)]
    first = answers[0]
    assert first["x"] == pytest.approx(0.30 * W_M, abs=0.01) and first["y"] == pytest.approx(0.60 * H_M, abs=0.01)
    assert first["heading"] == pytest.approx(0.0, abs=0.05)
    assert answers[1]["x"] == pytest.approx(W_M / 2 + 0.15) and answers[1]["y"] == pytest.approx(H_M / 2 + 0.10)
    assert answers[1]["heading"] == pytest.approx(math.pi / 4)
    bench = Benchmark(benchmark_path)
    for a in answers:  # each score is TD on the benchmark graph from the marked point to the truth
        ctx = MazeContext(a["run"], bench.graph(a["run"], "benchmark"))
        inst = LDHInstance(a["inst_idx"], a["run"], a["true_x"], a["true_y"], None, (), Variant.PREFIX)
        td, euclid, _ = score(ctx, ctx.one_hot(ctx.node_at(a["x"], a["y"])), inst)
        assert a["td"] == pytest.approx(td) and a["euclid"] == pytest.approx(euclid)

    # Ann's done page shows her marks beside the truth; Bob never saw the truth before his end.
    done = ann.inner_text("#your-answers")
    for a in answers[:2]:
        assert f"{a['true_x']:.2f}, {a['true_y']:.2f}" in done and f"{a['td']:.3f}" in done
    fresh = browser.new_context().new_page()
    fresh.goto(links["bob"])
    assert fresh.locator("#ldh-done").count() == 1

    admin.goto(study_url)
    admin.screenshot(path=str(ARTIFACTS / "ldh-study-results.png"), full_page=True)
    for name, rows in (("ann", answers[:2]), ("bob", answers[2:])):
        row = admin.locator(f"tr[data-participant={name}]")
        assert "2/2" in row.inner_text()
        assert row.locator("td.td").inner_text() == f"{sum(a['td'] for a in rows) / 2:.3f}"
    for position in (0, 1):
        row = admin.locator(f"#per-instance tr[data-position='{position}']")
        mean = sum(a["td"] for a in answers if a["position"] == position) / 2
        assert row.locator("td.td").inner_text() == f"{mean:.3f}" and "2/2" in row.inner_text()
    assert export["per_participant"][0]["td_mean"] == pytest.approx((answers[0]["td"] + answers[1]["td"]) / 2)

    exported = list(csv.DictReader(io.StringIO(admin.request.get(study_url + "/export.csv").text())))
    assert [(r["participant"], int(r["position"])) for r in exported] == [
        (a["participant"], a["position"]) for a in answers
    ]
    assert [float(r["td"]) for r in exported] == pytest.approx([a["td"] for a in answers])
    for page in (ann, bob, fresh, admin):
        page.context.close()


def test_a_participant_mid_study_never_sees_the_truth(browser, server, benchmark_path):
    studies = server.services.studies
    study_id = studies.create(1, "hidden", str(benchmark_path), "val_seen", "full", 2)
    carol = studies.invite(study_id, "carol")
    url = f"{server.url}/ldh/{StudyTokens(server.settings.signing_key()).issue(study_id, carol)}"
    instances = [{"true_x": i.true_x} for i in studies.instances(study_id)]
    page = browser.new_context().new_page()
    page.goto(url)
    answer_by_drag(page, 0.5, 0.5)
    page.wait_for_selector("h1:has-text('2 of 2')")
    truth_hidden(page, instances)
    answer_by_keyboard(page)
    page.wait_for_selector("#ldh-done")
    assert f"{instances[1]['true_x']:.2f}" in page.inner_text("#your-answers")  # now, at the end
    page.context.close()

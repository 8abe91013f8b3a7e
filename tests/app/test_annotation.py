"""Annotation: the annotator's login and pages (no names, no experimenter pages), annotation
events that survive a restart with their revisions, and Cohen's kappa against a hand-worked case."""

from __future__ import annotations

import html

import pytest

from app.annotation.agreement import agreement, cohen_kappa
from app.annotation.events import CutMarked, Tagged
from app.annotation.log import Annotation, AnnotationLog, TrialAnnotations
from app.db.models import AnnotationAssignment, Experimenter, Participant, Trial
from app.security import AccountRole, hash_password
from app.study.config import StudyFiles, template
from tests.app.live import browser, cli, experimenter_client, page_csrf_token, submit_login

PASSWORD = "annotate well"


def test_kappa_of_a_hand_worked_example():
    # 10 dialogs; the raters agree on 8 (p_o = 0.8), each says yes to 4 (p_e = .4*.4 + .6*.6 = 0.52):
    # kappa = (0.8 - 0.52) / (1 - 0.52) = 0.58333...
    a = [True, True, False, False, True, False, True, False, False, False]
    b = [True, False, False, False, True, False, True, True, False, False]
    assert cohen_kappa(a, b) == pytest.approx(0.28 / 0.48)
    assert cohen_kappa(a, a) == pytest.approx(1.0)
    assert cohen_kappa([True, False], [False, True]) == pytest.approx(-1.0)
    assert cohen_kappa([False] * 3, [False] * 3) is None  # p_e = 1: undefined, not a number made up
    with pytest.raises(ValueError, match="same items"):
        cohen_kappa([True], [True, False])


def test_agreement_lists_disagreements_and_cut_distances():
    def done(cut, *tags):
        return Annotation(cut=cut, tags={t: [1] for t in tags}, submitted=True)

    states = {
        1: TrialAnnotations({7: done(3, "needs_history"), 8: done(5, "needs_history")}),
        2: TrialAnnotations({7: done(2), 8: done(2, "needs_history")}, adjudicated={"needs_history": True}),
        3: TrialAnnotations({7: done(4)}),  # one annotator: not in the agreement
    }
    result = agreement(states, {7: "ann", 8: "bob"})
    assert result["double_annotated_trials"] == 2
    # needs_history: ann yes/no, bob yes/yes -> p_o 0.5, p_e .5*1 + .5*0 = 0.5 -> kappa 0
    assert result["kappa"]["needs_history"] == pytest.approx(0.0)
    assert result["kappa"]["surrender_control"] is None  # nobody gave it: undefined
    assert result["cut_distance"]["per_trial"] == {"1": 2, "2": 0} and result["cut_distance"]["mean"] == 1.0
    assert result["disagreements"] == [
        {"trial": 1, "item": "cut", "values": {"ann": 3, "bob": 5}, "adjudicated": None},
        {"trial": 2, "item": "needs_history", "values": {"ann": False, "bob": True}, "adjudicated": True},
    ]


def add_annotator(server, name: str, trial_id: int) -> int:
    with server.services.db.begin() as db:
        account = Experimenter(name=name, password_hash=hash_password(PASSWORD), role=AccountRole.ANNOTATOR)
        db.add(account)
        db.flush()
        db.add(AnnotationAssignment(trial_id=trial_id, annotator_id=account.id))
        return account.id


def annotator_browser(server, name: str):
    client = browser(server.url)
    page = submit_login(client, name, PASSWORD)
    assert page.status_code == 200 and str(page.url).endswith("/annotate"), (page.url, page.text[:300])
    return client, page


def post(client, trial_id: int, **data):
    page = client.get(f"/annotate/trials/{trial_id}")
    return client.post(f"/annotate/trials/{trial_id}", data={"csrf_token": page_csrf_token(page.text), **data})


def test_annotations_survive_a_restart_with_their_revisions(any_db_settings, start_server, trials):
    server = start_server(any_db_settings)
    trial = trials.new(server)
    ann = add_annotator(server, "ann", trial.id)
    client, _ = annotator_browser(server, "ann")
    assert post(client, trial.id, action="cut", cut="0").status_code == 200
    assert post(client, trial.id, action="cut", cut="0").status_code == 200  # a revision, kept beside the first
    assert post(client, trial.id, action="tag", tag="surrender_control", anchor="0").status_code == 422  # no message 0
    assert post(client, trial.id, action="tag", free_tag="Landmark naming").status_code == 200  # none anchored
    assert post(client, trial.id, action="cut", cut="3").status_code == 422  # the trial has no messages yet
    server.stop()
    server = start_server(any_db_settings)  # again, on the same database
    client, queue = annotator_browser(server, "ann")
    assert f"trial {trial.id}" in queue.text and "in progress" in queue.text and "0 of 1 trials submitted" in queue.text
    records = AnnotationLog(server.services.db).records(trial.id)
    assert [(r.annotator_id, r.event) for r in records] == [
        (ann, CutMarked(message=0)),
        (ann, CutMarked(message=0)),
        (ann, Tagged(tag="landmark naming", messages=[])),
    ]
    assert records[1].revises == records[0].id and records[0].revises is None and records[0].t_ns > 0
    page = client.get(f"/annotate/trials/{trial.id}").text
    assert "localized after message 0" in page
    assert (
        client.post(
            f"/annotate/trials/{trial.id}", data={"csrf_token": page_csrf_token(page), "action": "submit"}
        ).status_code
        == 200
    )
    assert "1 of 1 trials submitted" in client.get("/annotate").text
    assert AnnotationLog(server.services.db).state(trial.id).by_annotator[ann].submitted


def test_an_annotator_sees_no_names_and_no_experimenter_page(server, trial):
    add_annotator(server, "ann", trial.id)
    with server.services.db() as db:
        names = [p.name for p in db.query(Participant)]
    assert names, "the trial's team has participants"
    client, queue = annotator_browser(server, "ann")
    pages = [queue.text, client.get(f"/annotate/trials/{trial.id}").text]
    for text in pages:
        for name in [*names, "Team A"]:
            assert name not in html.unescape(text)
    # The experimenter's pages and data send an annotator home, and home is the annotator's queue.
    for path in ("/experimenter", f"/experimenter/trials/{trial.id}/replay.json", "/experimenter/annotation"):
        response = client.get(path, follow_redirects=False)
        assert response.status_code == 303 and response.headers["location"] == "/", path
        response = client.get(path)
        assert str(response.url) == server.url + "/annotate", path
        assert 'action="/experimenter/participants"' not in response.text and '"events"' not in response.text, path
    # Another trial (not in the queue) is not shown.
    assert client.get(f"/annotate/trials/{trial.id + 1}").status_code == 404


def test_admin_create_makes_annotators_and_refuses_an_unknown_role(tmp_path):
    env = {"ROBOTSLANG_DATA_DIR": str(tmp_path / "var"), "ROBOTSLANG_SECRET_KEY": "k"}
    made = cli("admin", "create", "ann", "--role", "annotator", "--password", PASSWORD, env=env)
    assert made.returncode == 0 and "annotator 'ann' created" in made.stdout, made.stderr
    refused = cli("admin", "create", "boss", "--role", "owner", "--password", PASSWORD, env=env)
    assert refused.returncode != 0 and "--role" in refused.stderr and "experimenter, annotator" in refused.stderr
    # An annotator stays one: `admin create` cannot turn the account into an experimenter.
    again = cli("admin", "create", "ann", "--password", PASSWORD, env=env)
    assert again.returncode != 0 and "exists as an annotator" in again.stderr


def test_a_study_file_declares_the_free_tags_its_annotators_may_use(server, trial):
    files = StudyFiles(server.services.settings.data_dir / "studies")
    config = template("pilot").model_copy(update={"annotation_tags": ["landmark naming", "map mismatch"]})
    files.save(config)
    with server.services.db.begin() as db:
        db.get(Trial, trial.id).study = "pilot"
    add_annotator(server, "ann", trial.id)
    client, _ = annotator_browser(server, "ann")
    page = client.get(f"/annotate/trials/{trial.id}").text
    assert '<option value="landmark naming">' in page and '<option value="map mismatch">' in page
    assert post(client, trial.id, action="tag", free_tag="Landmark naming").status_code == 200
    assert post(client, trial.id, action="tag", tag="needs_history").status_code == 200  # the five always go
    refused = post(client, trial.id, action="tag", free_tag="weather")
    assert refused.status_code == 422 and "landmark naming, map mismatch" in html.unescape(refused.text)
    tags = [r.event.tag for r in AnnotationLog(server.services.db).records(trial.id) if isinstance(r.event, Tagged)]
    assert tags == ["landmark naming", "needs_history"], "the refused tag left nothing in the log"


def test_the_experimenter_makes_an_annotator_on_the_annotation_page(server, trial):
    client = experimenter_client(server.services, server.url)
    page = client.get("/experimenter")
    assert 'href="/experimenter/annotation"' in page.text
    form = client.get("/experimenter/annotation").text
    made = client.post(
        "/experimenter/annotators",
        data={"csrf_token": page_csrf_token(form), "name": "ann", "password": PASSWORD, "study": "pilot"},
    )
    assert (
        made.status_code == 200 and "Created: ann." in made.text and str(made.url).endswith("study=pilot&created=ann")
    )
    short = client.post(
        "/experimenter/annotators", data={"csrf_token": page_csrf_token(form), "name": "bob", "password": "short"}
    )
    twice = client.post(
        "/experimenter/annotators", data={"csrf_token": page_csrf_token(form), "name": "ann", "password": PASSWORD}
    )
    assert short.status_code == 422 and "at least 8 characters" in short.text
    assert twice.status_code == 422 and "already exists" in html.unescape(twice.text)
    with server.services.db.begin() as db:
        (account,) = db.query(Experimenter).filter_by(name="ann").all()
        assert account.role == AccountRole.ANNOTATOR
        db.add(AnnotationAssignment(trial_id=trial.id, annotator_id=account.id))
    annotator, queue = annotator_browser(server, "ann")
    assert f"trial {trial.id}" in queue.text
    assert annotator.get("/experimenter", follow_redirects=False).status_code == 303

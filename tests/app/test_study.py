"""Participant studies over HTTP against a real server: the experimenter writes a versioned study;
strangers consent (recorded with the text's version), get a code, may give a private name, answer
a questionnaire after each trial, get the completion code, and withdraw (name and free text erased,
pseudonymous events kept). No public page or export carries a real name."""

from __future__ import annotations

import asyncio
import html
import json
import time

import httpx
import pytest
from click.testing import Result
from sqlalchemy import select, text
from typer.testing import CliRunner

from app.cli import root
from app.db.models import Event, Participant, StudyAnswer, StudyEvent, StudyParticipant, Trial
from app.study.config import StudyFiles, template
from app.trial.setup import create_team, create_trial
from bench.live import SeatClient
from sim.trial.events import LoggedEvent
from tests.app.live import (
    browser,
    experimenter_client,
    open_seats,
    page_csrf_token,
)

REAL_NAME = "Bob Okafor"
# As long as a participant may write, in a script of three bytes a character: past a page, so
# SQLite keeps it on overflow pages of its own.
FREE_TEXT = "I am Bob Okafor and the mug was hard to find. " + "杯子很难找到。" * 270


def make_study(settings, name: str = "pilot"):
    return StudyFiles(settings.data_dir / "studies").save(template(name))


def join(server, study: str, real_name: str = "", client: httpx.Client | None = None):
    """A stranger's browser through the study link: consent, code, optional name, instructions
    (`client`: a browser that has opened a panel's link already)."""
    client = client or browser(server.url)
    page = client.get(f"/study/{study}")
    assert page.status_code == 200 and "Information and consent" in page.text
    version = template(study).consent.version
    token = page_csrf_token(page.text)
    page = client.post(
        f"/study/{study}/consent", data={"choice": "agree", "consent_version": version, "csrf_token": token}
    )
    assert page.status_code == 200 and "Your participant code" in page.text, page.text[:300]
    code = page.text.split('id="participant-code">')[1].split("<")[0]
    page = client.post(f"/study/{study}/name", data={"real_name": real_name, "csrf_token": page_csrf_token(page.text)})
    assert "How it works" in page.text and "The Commander" in page.text
    client.headers["X-CSRF-Token"] = page_csrf_token(page.text)
    return client, code


def study_trial(server, study: str, codes: tuple[str, str]) -> int:
    """A trial of the study for the two participants (as the lobby will make: here by hand)."""
    services = server.services
    with services.db.begin() as db:
        a, b = (db.scalar(select(Participant.id).where(Participant.name == c)) for c in codes)
        team = create_team(db, f"{codes[0]}+{codes[1]}", a, b)
        maze = services.mazes.names()[0]
        trial = create_trial(
            db,
            team_id=team.id,
            maze=maze,
            targets=["mug", "jar", "paddle"],
            backend="sim",
            driver="human",
            commander_id=a,
            layouts={m: m for m in services.mazes.names()},
            now_ns=services.clock.now_ns(),
        )
        trial.study = study
        return trial.id


def answers(code: str, difficulty: str = "3", partner: str = "4", comments: str = "") -> dict[str, str]:
    return {"difficulty": difficulty, "partner": partner, "comments": comments}


def every_text_in_db(server) -> str:
    with server.services.engine.connect() as conn:
        tables = [r[0] for r in conn.execute(text("select name from sqlite_master where type='table'"))]
        return "\n".join(str(row) for t in tables for row in conn.execute(text(f'select * from "{t}"')))


def test_experimenter_writes_a_versioned_study_and_bad_input_changes_nothing(server):
    assert browser(server.url).get("/experimenter/studies").url.path == "/", "behind login"
    eve = experimenter_client(server.services, server.url)
    page = eve.post("/experimenter/studies", data={"name": "pilot"})
    assert page.status_code == 200 and "Study pilot, version 1" in page.text
    assert eve.post("/experimenter/studies", data={"name": "Bad Name!"}).text.count("lowercase letters") == 1

    files = StudyFiles(server.settings.data_dir / "studies")
    config = files.load("pilot").model_dump(mode="json")
    config["consent"] = {"version": "2026-12", "text": "New information."}
    saved = eve.post("/experimenter/studies/pilot", data={"config_json": json.dumps(config)})
    assert saved.status_code == 200 and "Saved as version 2" in saved.text
    assert files.load("pilot").version == 2 and files.load("pilot").consent.version == "2026-12"
    assert files.version("pilot", 1).consent.version == "1", "the version participants consented to before is kept"

    before = (server.settings.data_dir / "studies" / "pilot.json").read_text()
    for bad, says in [
        ({**config, "practice_maze": "Run_999"}, "practice_maze 'Run_999' is not a bundled maze"),
        ({**config, "maze_pool": ["nowhere"]}, "maze_pool names mazes this server does not have: nowhere"),
        ({**config, "completion_code": None, "redirect_url": None}, "give a completion_code or a redirect_url"),
        ({**config, "name": "other"}, "make a new study to use another name"),
    ]:
        page = eve.post("/experimenter/studies/pilot", data={"config_json": json.dumps(bad)})
        shown = html.unescape(page.text)
        assert page.status_code == 400 and says in shown, shown[:500]
        assert json.dumps(bad) in shown, "the posted text is shown again to fix"
    assert eve.post("/experimenter/studies/pilot", data={"config_json": "{not json"}).status_code == 400
    assert (server.settings.data_dir / "studies" / "pilot.json").read_text() == before
    # A forged row index adds no rows: the form adds at most its one blank row at the end.
    forged = eve.post(
        "/experimenter/studies/pilot", data={"questionnaire.99999999.prompt": "x", "questionnaire.x.id": "y"}
    )
    assert forged.status_code == 200 and len(files.load("pilot").questionnaire) == 3


def test_the_study_editor_is_a_form_over_the_same_study(server):
    eve = experimenter_client(server.services, server.url)
    page = eve.post("/experimenter/studies", data={"name": "pilot"}).text
    assert f'value="{server.url}/study/pilot"' in page, "the participants' link, whole"
    files = StudyFiles(server.settings.data_dir / "studies")
    form = {
        "title": "Robots in mazes",
        "consent.version": "2",
        "trials_per_participant": "3",
        "max_participants": "",  # unset
        "maze_pool": "gen-001\n gen-002 \n",
        "questionnaire.0.id": "",  # the first item removed
        "questionnaire.0.prompt": "",
        "questionnaire.3.id": "fun",  # the blank row: an item added
        "questionnaire.3.kind": "difficulty",
        "questionnaire.3.prompt": "How much fun was it? (1-5)",
        "outcome_codes.partial": "PART-1",
        "outcome_codes.withdrew": "",
        "panel_on": "on",
        "panel.completion_url": "https://app.prolific.com/submissions/complete?cc={code}",
    }
    saved = eve.post("/experimenter/studies/pilot", data=form)
    assert saved.status_code == 200 and "Saved as version 2" in saved.text
    study = files.load("pilot")
    assert (study.title, study.consent.version, study.trials_per_participant) == ("Robots in mazes", "2", 3)
    assert study.max_participants is None and study.maze_pool == ["gen-001", "gen-002"]
    assert [q.id for q in study.questionnaire] == ["partner", "comments", "fun"]
    assert study.outcome_codes == {"partial": "PART-1"} and study.panel is not None
    assert study.panel.participant_param == "PROLIFIC_PID", "the panel's defaults, shown in the form"
    assert study.consent.text == template("pilot").consent.text, "a field not sent is kept"

    # A bad value: said, the typed values shown again, nothing saved; without panel_on, no panel.
    before = (server.settings.data_dir / "studies" / "pilot.json").read_text()
    page = eve.post("/experimenter/studies/pilot", data={"title": "Renamed", "trials_per_participant": "0"})
    shown = html.unescape(page.text)
    assert page.status_code == 400 and "trials_per_participant: Input should be greater than or equal to 1" in shown
    assert 'name="title" type="text" value="Renamed"' in shown
    assert (server.settings.data_dir / "studies" / "pilot.json").read_text() == before
    assert eve.post("/experimenter/studies/pilot", data={"title": "Renamed"}).status_code == 200
    assert files.load("pilot").panel is None and files.load("pilot").title == "Renamed"


def test_consent_is_recorded_with_its_version_and_declining_records_no_one(server):
    make_study(server.settings)
    assert browser(server.url).get("/study/nosuch").status_code == 404
    stranger = browser(server.url)
    token = page_csrf_token(stranger.get("/study/pilot").text)
    stale = stranger.post("/study/pilot/consent", data={"choice": "agree", "consent_version": "0", "csrf_token": token})
    assert stale.status_code == 409 and "read it again" in stale.text
    declined = stranger.post(
        "/study/pilot/consent", data={"choice": "decline", "consent_version": "1", "csrf_token": token}
    )
    assert "You chose not to take part" in declined.text
    assert stranger.get("/study/pilot/me").status_code == 403, "declining gives no pass"

    client, code = join(server, "pilot")
    assert client.get("/study/pilot").url.path == "/study/pilot/me", "the pass brings a participant back"
    with server.services.db() as db:
        participants = list(db.scalars(select(Participant.name)))
        events = [(e.kind, e.participant_id is None, e.payload) for e in db.scalars(select(StudyEvent))]
    assert participants == [code]
    assert events == [
        ("declined", True, {"study_version": 1, "consent_version": "1"}),
        ("consented", False, {"study_version": 1, "consent_version": "1"}),
    ]
    other = browser(server.url)
    other.cookies.set("robotslang_study", "forged", path="/study")
    assert other.get("/study/pilot/me").status_code == 403


def agree(server, study: str = "pilot", address: str | None = None):
    """A new browser (at `address`) agreeing on the study's information page: the browser, ready
    for the study's pages' scripts, and the reply."""
    client = browser(server.url, address)
    token = page_csrf_token(client.get(f"/study/{study}").text)
    reply = client.post(
        f"/study/{study}/consent", data={"choice": "agree", "consent_version": "1", "csrf_token": token}
    )
    client.headers["X-CSRF-Token"] = page_csrf_token(reply.text)
    return client, reply


def participants(server) -> int:
    with server.services.db() as db:
        return len(db.scalars(select(StudyParticipant)).all())


@pytest.mark.settings(
    study_consent_limit_per_address="3/minute",
    study_consent_limit_per_study="5/minute",
    study_lobby_limit_per_address="2/minute",
)
def test_sign_ups_are_limited_per_address_and_per_study_and_lobby_joins_per_address(server):
    make_study(server.settings)
    looped = [agree(server) for _ in range(5)]  # one address, a new browser each time
    assert [reply.status_code for _, reply in looped] == [200, 200, 200, 429, 429]
    busy = looped[-1][1]
    assert "Please try again in" in busy.text and int(busy.headers["Retry-After"]) > 0
    # Another address still signs up, until the study's own rate is spent (5 a minute from anyone).
    others = [agree(server, address=f"127.0.0.{i}")[1] for i in (2, 3, 4)]
    assert [reply.status_code for reply in others] == [200, 200, 429]
    assert participants(server) == 5, "nothing recorded for the refused"
    # Lobby joins from one address: the third participant to enter the lobby from it waits a while.
    lobby = [client for client, _ in looped[:3]]
    assert poll(lobby[0])["state"] == "waiting" and poll(lobby[1])["state"] == "seated"
    refused = lobby[2].post("/study/pilot/lobby")
    assert refused.status_code == 429 and "joining the lobby" in refused.json()["detail"]
    assert poll(lobby[0])["state"] == "seated", "asking again once in is not joining again"


def test_a_study_with_a_cap_turns_the_next_participant_away_with_a_page(server):
    StudyFiles(server.settings.data_dir / "studies").save(template("pilot").model_copy(update={"max_participants": 2}))
    assert [agree(server)[1].status_code for _ in range(2)] == [200, 200]
    page = browser(server.url).get("/study/pilot")
    assert page.status_code == 200 and "This study is full" in page.text and "All 2 places" in page.text
    assert 'id="agree"' not in page.text, "no consent form to fill in for nothing"
    _, late = agree(server)  # a consent page opened before the cap was reached
    assert late.status_code == 409 and "This study is full" in late.text
    assert participants(server) == 2


def test_questionnaires_completion_and_withdrawal_erase_personal_data_only(server, tmp_path, trials):
    # One planned trial: once it is played, "I have finished" gives the plan's code.
    StudyFiles(server.settings.data_dir / "studies").save(
        template("pilot").model_copy(update={"trials_per_participant": 1})
    )
    bob, bob_code = join(server, "pilot", real_name=REAL_NAME)
    ann, ann_code = join(server, "pilot")
    trial_id = study_trial(server, "pilot", (bob_code, ann_code))
    url = f"/study/pilot/trials/{trial_id}/questionnaire"

    early = bob.post(url, data=answers(bob_code, comments=FREE_TEXT))
    assert early.status_code == 400 and "opens when the trial is over" in early.text
    after = f"/study/pilot/trials/{trial_id}/next"
    assert bob.get(after, follow_redirects=False).headers["location"] == "/study/pilot/me", "not over yet"
    eve = experimenter_client(server.services, server.url)
    open_seats(server, trial_id, "commander", "driver")
    assert eve.post(f"/experimenter/trials/{trial_id}/abort").status_code == 200
    # The seat page's "Continue" leads to the questionnaire of a trial played, then to their page.
    assert bob.get(after, follow_redirects=False).headers["location"] == url
    outsider, _ = join(server, "pilot")
    assert "not one of yours" in outsider.post(url, data=answers("x")).text
    bad = bob.post(url, data=answers(bob_code, partner="7", comments=FREE_TEXT))
    assert bad.status_code == 400 and "needs a rating from 1 to 5" in bad.text and FREE_TEXT in bad.text
    assert bob.post(url, data=answers(bob_code, comments=FREE_TEXT)).url.path == "/study/pilot/me"
    assert "answered" in bob.get("/study/pilot/me").text
    assert bob.get(after, follow_redirects=False).headers["location"] == "/study/pilot/me"
    assert "already answered" in bob.post(url, data=answers(bob_code)).text
    assert ann.post(url, data=answers(ann_code, difficulty="5", partner="2")).status_code == 200
    with server.services.db() as db:
        rows = {a.study_participant_id: (a.ratings, a.free_text) for a in db.scalars(select(StudyAnswer))}
    assert sorted(rows.values(), key=str) == sorted(
        [({"difficulty": 3, "partner": 4}, {"comments": FREE_TEXT}), ({"difficulty": 5, "partner": 2}, None)], key=str
    )

    done = ann.post("/study/pilot/complete")
    assert 'id="completion-code">DONE-PILOT<' in done.text

    # The experimenter (logged in) sees the private name; no public page or export does.
    assert REAL_NAME in eve.get("/experimenter/studies/pilot").text
    public = browser(server.url)
    seat = trials.of(trial_id).tokens["driver"]
    values = {"token": seat, "trial_id": trial_id, "name": "pilot", "index": 0, "position": 0, "frame_id": 1}
    values |= {"study_id": 1, "participant_id": 1, "team_id": 1, "robot_id": 1, "action": "pause"}
    searched = []
    for template_path, methods in server.app.openapi()["paths"].items():  # every route the server has
        if "get" not in methods:
            continue
        path = template_path.format(**values)
        for who, client in (("public", public), ("participant", ann), ("experimenter's export", eve)):
            if who == "experimenter's export" and not path.startswith("/experimenter/trials/"):
                continue  # the experimenter's own pages may show the private name; exports may not
            reply = client.get(path)
            if reply.status_code == 200:
                searched.append(path)
                assert REAL_NAME.encode() not in reply.content, (who, path)
    assert {
        "/",
        "/leaderboard",
        "/study/pilot/me",
        f"/experimenter/trials/{trial_id}/export.mcap",
    } <= set(searched), searched
    env = {"ROBOTSLANG_DATA_DIR": str(server.settings.data_dir), "ROBOTSLANG_SECRET_KEY": "test-secret"}
    for fmt in ("mcap", "ndh"):
        out = tmp_path / fmt
        result: Result = CliRunner().invoke(
            root, ["export", "all", "--include-aborted", "--format", fmt, "--out", str(out)], env=env
        )
        assert result.exit_code == 0, result.output
        written = [p for p in out.rglob("*") if p.is_file()]
        assert written, f"{fmt}: the aborted study trial is exported"
        assert not [p for p in written if REAL_NAME.encode() in p.read_bytes()], fmt

    gone = bob.post("/study/pilot/withdraw", data={"confirm": "yes"})
    assert "You have withdrawn" in gone.text
    assert bob.get("/study/pilot/me").status_code == 403, "the pass is gone with the cookie"
    assert REAL_NAME not in every_text_in_db(server) and FREE_TEXT not in every_text_in_db(server)
    # Nor in the files' bytes: not in the database's free space, not in a stale frame of the WAL
    # (the free text as stored: in a JSON column, its characters escaped).
    erased = [REAL_NAME.encode(), FREE_TEXT.encode(), json.dumps(FREE_TEXT)[1:-1].encode()]
    for path in [server.settings.data_dir / f"robotslang.db{suffix}" for suffix in ("", "-wal")]:
        raw = path.read_bytes() if path.exists() else b""
        assert not [text[:20] for text in erased if text in raw], path.name
    with server.services.db() as db:
        enrolled = db.scalar(select(StudyParticipant).join(Participant).where(Participant.name == bob_code))
        kinds = [
            e.kind for e in db.scalars(select(StudyEvent).where(StudyEvent.participant_id == enrolled.participant_id))
        ]
        trial = db.get(Trial, trial_id)
        ratings = db.scalar(select(StudyAnswer.ratings).where(StudyAnswer.study_participant_id == enrolled.id))
    assert enrolled.withdrawn_at is not None and enrolled.real_name is None
    assert kinds == ["consented", "answered", "withdrawn"], "pseudonymous events remain"
    assert trial.commander_id == enrolled.participant_id and ratings == {"difficulty": 3, "partner": 4}


def test_the_questionnaire_opens_only_for_a_trial_the_participant_played_that_has_ended(server):
    make_study(server.settings)
    bob, bob_code = join(server, "pilot")
    ann_code, cat_code, dan_code = (join(server, "pilot")[1] for _ in range(3))
    ours, theirs = (
        study_trial(server, "pilot", (bob_code, ann_code)),
        study_trial(server, "pilot", (cat_code, dan_code)),
    )
    form = "/study/pilot/trials/{}/questionnaire"
    open_seats(server, ours, "commander", "driver")
    running = bob.get(form.format(ours))
    assert running.status_code == 404 and "opens when the trial is over" in running.text
    eve = experimenter_client(server.services, server.url)
    for trial_id in (ours, theirs):
        open_seats(server, trial_id, "commander", "driver")
        assert eve.post(f"/experimenter/trials/{trial_id}/abort").status_code == 200
    other_pairs = bob.get(form.format(theirs), headers={"Accept": "text/html"})
    assert other_pairs.status_code == 404 and "not one of yours" in other_pairs.text
    # The error page leads back into the study, and nowhere out of it.
    assert '<a href="/study/pilot" id="back-to-study">' in other_pairs.text
    assert 'href="/"' not in other_pairs.text and 'href="/leaderboard"' not in other_pairs.text
    assert bob.get(form.format(theirs + 1000)).status_code == 404, "no such trial"
    page = bob.get(form.format(ours))
    assert page.status_code == 200 and 'name="difficulty"' in page.text
    assert bob.post(form.format(ours), data=answers(bob_code)).url.path == "/study/pilot/me"
    answered = bob.get(form.format(ours))
    assert answered.status_code == 404 and "already answered" in answered.text


def poll(client, study: str = "pilot") -> dict:
    reply = client.post(f"/study/{study}/lobby")
    assert reply.status_code == 200, reply.text[:300]
    return reply.json()


def test_newcomers_practise_together_on_the_bundled_maze_set_aside_from_scores(server):
    StudyFiles(server.settings.data_dir / "studies").save(template("pilot"))
    (ann, ann_code), (bob, bob_code) = join(server, "pilot"), join(server, "pilot")
    assert poll(ann)["state"] == "waiting" and poll(bob)["state"] == "seated"
    eve = experimenter_client(server.services, server.url)
    with server.services.db() as db:
        practice = db.scalar(select(Trial).where(Trial.study == "pilot"))
    assert practice.maze == "gen-000" and practice.excluded_reason == "study practice: not scored"
    assert eve.post(f"/experimenter/trials/{practice.id}/abort").status_code == 200
    refused = ann.post(f"/study/pilot/trials/{practice.id}/questionnaire", data=answers(""))
    assert refused.status_code == 400 and "practice trial has no questionnaire" in refused.text
    after = ann.get(f"/study/pilot/trials/{practice.id}/next", follow_redirects=False)
    assert after.headers["location"] == "/study/pilot/lobby", "on from the practice to the first real trial"
    assert "practice: no questionnaire" in ann.get("/study/pilot/me").text
    cat, cat_code = join(server, "pilot")
    codes = (ann_code, bob_code, cat_code)
    assert poll(ann)["state"] == "waiting" and poll(cat) == {"state": "waiting", "waiting": 2}, (
        "a newcomer is not paired with someone who has practised"
    )
    real = poll(bob)
    assert real["state"] == "seated"
    with server.services.db() as db:
        trial = db.scalars(select(Trial).where(Trial.study == "pilot").order_by(Trial.id.desc())).first()
    assert trial.maze != "gen-000" and trial.excluded_reason is None

    # The study page lists its trials by kind, and each participant's trials against the plan.
    page = eve.get("/experimenter/studies/pilot").text
    assert f'<tr data-trial="{practice.id}" data-kind="practice">' in page
    assert f'<tr data-trial="{trial.id}" data-kind="live">' in page
    progress = {
        code: page.split(f'<tr data-code="{code}">')[1].split('class="progress">')[1].split("<")[0] for code in codes
    }
    assert progress == {ann_code: "1 of 5, practised", bob_code: "1 of 5, practised", cat_code: "0 of 5"}


def test_lobby_pairs_whoever_arrives_on_unseen_layouts_with_roles_balanced(any_db_settings, start_server):
    """On SQLite and on PostgreSQL (the lobby's times come back with and without their zone)."""
    lobby_rounds(start_server(any_db_settings))


def lobby_rounds(server) -> None:
    files = StudyFiles(server.settings.data_dir / "studies")
    files.save(template("pilot").model_copy(update={"lobby_presence_s": 3.0, "practice_maze": None}))
    files.save(template("quick").model_copy(update={"lobby_timeout_s": 1.0}))
    ann, ann_code = join(server, "pilot")
    assert "Waiting for a partner" in ann.get("/study/pilot/lobby").text
    assert poll(ann) == {"state": "waiting", "waiting": 1}
    bob, _ = join(server, "pilot")
    cat, cat_code = join(server, "pilot")
    assert poll(ann)["state"] == "waiting"  # her page asks again while the others arrive
    assert poll(bob)["state"] == "seated", "two waiting: the second to ask is paired"
    assert poll(ann)["state"] == "seated"
    # Bob's partner is Ann; now Bob's page closes before anyone else comes (he stops asking).
    eve = experimenter_client(server.services, server.url)
    end(server, eve)
    assert poll(bob)["state"] == "waiting"
    time.sleep(3.5)  # past the study's lobby_presence_s
    seated = poll(cat)
    assert seated == {"state": "waiting", "waiting": 1}, "Bob left the lobby: Cat is not paired with him"
    ann_seat = poll(ann)
    cat_seat = poll(cat)
    assert ann_seat["state"] == cat_seat["state"] == "seated"
    assert {ann_seat["role"], cat_seat["role"]} == {"commander", "driver"}
    assert cat_seat["role"] == "commander", "Ann commanded before (or waited longer): Cat commands now"
    second_browser = browser(server.url)
    second_browser.cookies = ann.cookies
    second_browser.headers["X-CSRF-Token"] = ann.headers["X-CSRF-Token"]
    again = poll(second_browser)
    seat_of_link = server.services.seats.verify  # links are stamped when issued: compare the seats they open
    assert seat_of_link(again["link"].removeprefix("/play/")) == seat_of_link(
        ann_seat["link"].removeprefix("/play/")
    ), "a second browser of Ann gets her one seat, not another"
    assert browser(server.url).get(ann_seat["link"]).status_code == 200
    with server.services.db() as db:
        trials = list(db.scalars(select(Trial).where(Trial.study == "pilot").order_by(Trial.id)))
        names = dict(db.execute(select(Participant.id, Participant.name)).all())
    assert len(trials) == 2 and trials[0].maze != trials[1].maze, "Ann never gets a layout twice"
    assert names[trials[1].commander_id] == cat_code and names[trials[1].driver_id] == ann_code

    lone, _ = join(server, "quick")
    assert poll(lone, "quick")["state"] == "waiting"
    time.sleep(1.2)
    assert poll(lone, "quick")["state"] == "timed_out"


def test_the_experimenter_pairs_by_hand_by_the_lobbys_rules(server):
    StudyFiles(server.settings.data_dir / "studies").save(template("pilot"))
    (ann, ann_code), (bob, bob_code) = join(server, "pilot"), join(server, "pilot")
    eve = experimenter_client(server.services, server.url)
    for a, b, says in [
        (ann_code, ann_code, "choose two different participants"),
        (ann_code, "P-NOBODY", "no participant &#39;P-NOBODY&#39; in study &#39;pilot&#39;"),
    ]:
        page = eve.post("/experimenter/studies/pilot/pair", data={"a": a, "b": b})
        assert says in page.text, page.text[:300]
    assert browser(server.url).get("/experimenter/studies/pilot/lobby").url.path == "/", "behind login"
    assert poll(ann)["state"] == "waiting"
    live = eve.get("/experimenter/studies/pilot/lobby").json()["waiting"]
    assert [(w["code"], w["teams"], w["practice"]) for w in live] == [(ann_code, 0, True)]
    assert "study_lobby_live.js" in eve.get("/experimenter/studies/pilot").text
    page = eve.post("/experimenter/studies/pilot/pair", data={"a": ann_code, "b": bob_code})
    assert "Paired: trial" in page.text
    assert eve.get("/experimenter/studies/pilot/lobby").json() == {"waiting": []}, "paired: out of the lobby"
    assert poll(ann)["state"] == poll(bob)["state"] == "seated", "their lobby pages open their seats"
    again = eve.post("/experimenter/studies/pilot/pair", data={"a": ann_code, "b": bob_code})
    assert "one of them is in a live trial" in again.text
    with server.services.db() as db:
        assert [t.maze for t in db.scalars(select(Trial).where(Trial.study == "pilot"))] == ["gen-000"]


def test_the_lobby_stops_pairing_a_participant_who_played_the_plans_trials(server):
    plan = {"practice_maze": None, "trials_per_participant": 1}
    StudyFiles(server.settings.data_dir / "studies").save(template("pilot").model_copy(update=plan))
    (ann, _), (bob, _), (cat, _) = join(server, "pilot"), join(server, "pilot"), join(server, "pilot")
    assert poll(ann)["state"] == "waiting" and poll(bob)["state"] == "seated"
    eve = experimenter_client(server.services, server.url)
    end(server, eve)
    assert poll(ann) == {"state": "all_played", "trials": 1, "teams": 1}
    assert poll(cat) == {"state": "waiting", "waiting": 1}, "Ann, done, does not wait"


def end(server, eve, trial_id: int | None = None) -> None:
    """Both seats of the study's live trial open, then the experimenter aborts it (played: it counts)."""
    if trial_id is None:
        with server.services.db() as db:
            trial_id = db.scalar(select(Trial.id).where(Trial.study == "pilot", Trial.phase == "waiting"))
    open_seats(server, trial_id, "commander", "driver")
    assert eve.post(f"/experimenter/trials/{trial_id}/abort").status_code == 200


def test_the_lobby_pairs_by_the_team_plan_and_stops_at_the_plans_teams(server):
    plan = {"practice_maze": None, "teams_per_participant": 2, "trials_per_participant": 10}
    StudyFiles(server.settings.data_dir / "studies").save(template("pilot").model_copy(update=plan))
    (ann, ann_code), (bob, bob_code), (cat, cat_code) = (join(server, "pilot") for _ in range(3))
    eve = experimenter_client(server.services, server.url)
    assert poll(ann)["state"] == "waiting" and poll(bob)["state"] == "seated"
    assert poll(cat)["state"] == "waiting"
    end(server, eve)
    second = poll(ann)
    assert second["state"] == "seated" and second["role"] == "driver", "Ann commanded with Bob: she drives now"
    end(server, eve)
    assert poll(ann) == {"state": "all_played", "trials": 2, "teams": 2}, "two teams: Ann's plan is done"
    assert poll(bob)["state"] == "waiting" and poll(cat)["state"] == "seated"
    with server.services.db() as db:
        names = dict(db.execute(select(Participant.id, Participant.name)).all())
        teams = [
            {names[t.commander_id], names[t.driver_id]}
            for t in db.scalars(select(Trial).where(Trial.study == "pilot").order_by(Trial.id))
        ]
    assert teams == [{ann_code, bob_code}, {ann_code, cat_code}, {bob_code, cat_code}]


async def hold_seat(server, link: str, seconds: float) -> None:
    """A participant's seat page open for `seconds` (its socket joins the trial)."""
    async with SeatClient(server.ws_url, link.removeprefix("/play/")) as seat:
        await seat.wait_for(lambda message: True)
        await asyncio.sleep(seconds)


def test_a_partner_who_never_opens_their_seat_aborts_the_trial_and_the_other_is_paired_again(server):
    maze = server.services.mazes.names()[0]
    # Ann's seat opens well within the deadline, on a loaded machine too; Bob's never does.
    plan = {"practice_maze": None, "join_timeout_s": 3.0, "maze_pool": [maze], "trials_per_participant": 1}
    StudyFiles(server.settings.data_dir / "studies").save(template("pilot").model_copy(update=plan))
    (ann, ann_code), (bob, _), (cat, cat_code) = (join(server, "pilot") for _ in range(3))
    assert poll(bob)["state"] == "waiting"
    ann_seat = poll(ann)
    assert ann_seat["role"] == "driver", "Bob waited longer: he commands"
    asyncio.run(hold_seat(server, ann_seat["link"], 4.0))  # Bob never opens his: nobody sees the map
    with server.services.db() as db:
        trial = db.scalar(select(Trial).where(Trial.study == "pilot"))
        reasons = [e.payload.get("reason") for e in db.scalars(select(Event).where(Event.trial_id == trial.id))]
    assert trial.phase == "aborted" and "the commander never joined" in reasons
    # Nothing to rate in a trial that never started: Ann's seat page sends her back to the lobby.
    after = ann.get(f"/study/pilot/trials/{trial.id}/next", follow_redirects=False)
    assert after.status_code == 303 and after.headers["location"] == "/study/pilot/lobby"
    refused = ann.post(f"/study/pilot/trials/{trial.id}/questionnaire", data=answers(ann_code))
    assert refused.status_code == 400 and "never started" in refused.text
    assert "never started: no questionnaire" in ann.get("/study/pilot/me").text
    seat_page = ann.get(ann_seat["link"]).text
    assert f'href="/study/pilot/trials/{trial.id}/next" id="continue"' in seat_page
    assert poll(ann) == {"state": "waiting", "waiting": 1}, "the trial does not count: Ann waits for another"
    with server.services.db() as db:
        since = db.scalar(select(StudyParticipant.lobby_since).join(Participant).where(Participant.name == ann_code))
    assert since == trial.created_at, "Ann waits from when she was first paired: the head of the lobby"
    seated = poll(cat)
    assert seated["state"] == "seated", "Bob left the lobby; Ann and Cat are paired on the one layout of the pool"
    with server.services.db() as db:
        names = dict(db.execute(select(Participant.id, Participant.name)).all())
        second = db.scalars(select(Trial).where(Trial.study == "pilot").order_by(Trial.id.desc())).first()
    assert second.maze == maze and {names[second.commander_id], names[second.driver_id]} == {ann_code, cat_code}


@pytest.mark.slow
def test_a_paired_trials_join_deadline_outlives_a_server_crash(settings, server_process):
    timeout_s = 4.0
    plan = {"practice_maze": None, "join_timeout_s": timeout_s}
    StudyFiles(settings.data_dir / "studies").save(template("pilot").model_copy(update=plan))
    server = server_process()
    services = server.services

    def log() -> list[LoggedEvent]:
        with services.db() as db:
            trial_id = db.scalar(select(Trial.id).where(Trial.study == "pilot"))
        return services.log.load(trial_id)

    try:
        server.start()
        (ann, _), (bob, _) = join(server, "pilot"), join(server, "pilot")
        assert poll(ann)["state"] == "waiting" and poll(bob)["state"] == "seated"
        server.kill()  # at once: neither seat opened, the deadline seconds away
        time.sleep(timeout_s + 0.5)  # down past the deadline
        server.start()  # and nobody comes
        up_ns = time.time_ns()  # it answers only once started: a trial it reopened is open by now
        deadline = time.monotonic() + 30
        while log()[-1].payload.get("phase") != "aborted":
            assert time.monotonic() < deadline, "the restarted server never aborted the unjoined trial"
            time.sleep(0.2)
    finally:
        server.stop()
    events = log()
    created, aborted = events[0], events[-1]
    assert "never joined" in aborted.payload["reason"]
    assert aborted.t_ns >= created.t_ns + timeout_s * 1e9, "never early"
    # Due while the server was down: aborted as it reopened the trial, not a fresh timeout later.
    assert aborted.t_ns < up_ns, "the deadline counts from the pairing, not from the restart"


def test_a_participant_who_left_the_lobby_waits_anew_on_coming_back(server):
    quick = {"practice_maze": None, "lobby_presence_s": 2.0, "lobby_timeout_s": 3.0}
    StudyFiles(server.settings.data_dir / "studies").save(template("pilot").model_copy(update=quick))
    ann, _ = join(server, "pilot")
    assert poll(ann)["state"] == "waiting"
    time.sleep(3.3)  # her tab closed past the time-out: she had left the lobby, not waited in it
    assert poll(ann) == {"state": "waiting", "waiting": 1}, "back: a new wait, not a timed-out one"
    for pause in (1.0, 1.0):
        time.sleep(pause)
        assert poll(ann)["state"] == "waiting"
    time.sleep(1.3)
    assert poll(ann)["state"] == "timed_out", "asking all along past lobby_timeout_s"

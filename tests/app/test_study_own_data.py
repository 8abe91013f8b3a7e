"""A participant's own data, against a real server: everything recorded about them downloads from
their page as JSON (and nobody else's); a study's personal data (names, free text, panel
identifiers) are deleted `purge_after_days` after it closes, by `robotslang study purge` and at a
server's start (time faked by the study's closing date); withdrawal and logout make the browser
forget the site (Clear-Site-Data); over TLS the cookies are __Host- and Secure."""

from __future__ import annotations

import asyncio
from datetime import UTC, datetime, timedelta

import httpx
import pytest
from sqlalchemy import select
from typer.testing import CliRunner

from app.cli import root
from app.db.models import StudyAnswer, StudyEvent, StudyParticipant
from app.study.config import StudyFiles
from tests.app.live import TrialHandle, browser, experimenter_client, page_csrf_token
from tests.app.test_study import answers, join, poll
from tests.app.test_study_panel import arrive, stored
from tests.app.test_study_paths import study

PROLIFIC = {"completion_url": "https://app.prolific.com/submissions/complete?cc={code}"}


def played(server, ann, bob) -> int:
    """Ann and Bob paired and their trial played a little (Ann says hello), then ended."""
    assert poll(ann)["state"] == "waiting"
    seat = poll(bob)
    ann_role = "driver" if seat["role"] == "commander" else "commander"
    trial = TrialHandle.on(server, server.services.seats.verify(seat["link"].rsplit("/play/", 1)[1]).trial_id)

    async def talk() -> None:
        async with trial.seat(ann_role) as mine:
            await mine.wait_for(lambda m: m["type"] == "welcome")
            async with trial.seat(seat["role"]) as theirs:
                await theirs.wait_for(lambda m: m["type"] == "welcome")
                await mine.send("chat", text="hello from Ann")
                await theirs.wait_for(lambda m: m.get("payload", {}).get("text") == "hello from Ann")

    asyncio.run(talk())
    eve = experimenter_client(server.services, server.url)
    assert eve.post(f"/experimenter/trials/{trial.id}/abort").status_code == 200
    return trial.id


def test_a_participant_downloads_everything_recorded_about_them_and_nobody_elses(server):
    StudyFiles.of(server.settings.data_dir).save(study("pilot", practice_maze=None, panel=PROLIFIC))
    ann, ann_code = arrive(server, "PID-ANN", "SE-1")
    ann.post("/study/pilot/name", data={"real_name": "Ann Real"})
    bob, bob_code = arrive(server, "PID-BOB", "SE-2")
    trial_id = played(server, ann, bob)
    url = f"/study/pilot/trials/{trial_id}/questionnaire"
    assert ann.post(url, data=answers(ann_code, comments="my own words")).status_code == 200
    assert bob.post(url, data=answers(bob_code, comments="bob's words")).status_code == 200
    assert 'id="my-data"' in ann.get("/study/pilot/me").text

    download = ann.get("/study/pilot/me/data.json")
    assert download.status_code == 200 and "attachment" in download.headers["content-disposition"]
    mine = download.json()
    assert (mine["participant"], mine["real_name"], mine["consent_version"]) == (ann_code, "Ann Real", "1")
    assert mine["panel"] == {"participant": "PID-ANN", "study": "ST-77", "session": "SE-1"}
    assert [e["kind"] for e in mine["study_events"]] == ["consented", "answered"]
    assert mine["study_events"][0]["consent_version"] == "1"
    assert mine["answers"] == [
        {
            "trial_id": trial_id,
            "ratings": {"difficulty": 3, "partner": 4},
            "free_text": {"comments": "my own words"},
            "at": mine["answers"][0]["at"],
        }
    ]
    (trial,) = mine["trials"]
    said = [e["text"] for e in trial["events"] if e["kind"] == "chat"]
    assert trial["trial_id"] == trial_id and said == ["hello from Ann"]
    assert {e.get("role") for e in trial["events"] if "role" in e} == {trial["seat"]}, "only her seat's events"
    text = download.text
    assert bob_code not in text and "bob's words" not in text and "PID-BOB" not in text
    assert browser(server.url).get("/study/pilot/me/data.json").status_code == 403, "no pass: nobody's data"


def purge_cli(server, *args: str) -> str:
    env = {"ROBOTSLANG_DATA_DIR": str(server.settings.data_dir), "ROBOTSLANG_SECRET_KEY": "test-secret"}
    done = CliRunner().invoke(root, ["study", "purge", *args], env=env)
    assert done.exit_code == 0, done.output
    return done.output


def personal(server) -> list[tuple]:
    with server.services.db() as db:
        people = db.execute(
            select(
                StudyParticipant.real_name,
                StudyParticipant.panel_participant,
                StudyParticipant.panel_study,
                StudyParticipant.panel_session,
            )
        ).all()
        return [tuple(p) for p in people] + [(a.free_text,) for a in db.scalars(select(StudyAnswer))]


def test_personal_data_are_purged_the_set_days_after_the_study_closes(start_server):
    server = start_server()
    files = StudyFiles.of(server.settings.data_dir)
    files.save(study("pilot", practice_maze=None, panel=PROLIFIC, purge_after_days=30))
    ann, ann_code = arrive(server, "PID-ANN", "SE-1")
    ann.post("/study/pilot/name", data={"real_name": "Ann Real"})
    bob, bob_code = arrive(server, "PID-BOB", "SE-2")
    trial_id = played(server, ann, bob)
    ann.post(f"/study/pilot/trials/{trial_id}/questionnaire", data=answers(ann_code, comments="my own words"))
    before = personal(server)
    assert ("Ann Real", "PID-ANN", "ST-77", "SE-1") in before and ({"comments": "my own words"},) in before

    closed = study("pilot", practice_maze=None, panel=PROLIFIC, purge_after_days=30)
    files.save(closed.model_copy(update={"closed_at": datetime.now(UTC) - timedelta(days=29)}))
    assert "not due" in purge_cli(server, "--study", "pilot") and personal(server) == before
    page = browser(server.url).get("/study/pilot")
    assert page.status_code == 410 and "This study has closed" in page.text, "closed: no one new consents"

    files.save(closed.model_copy(update={"closed_at": datetime.now(UTC) - timedelta(days=31)}))
    assert "personal data of 2 participant(s) deleted" in purge_cli(server)
    assert personal(server) == [(None, None, None, None)] * 2 + [(None,)]
    with server.services.db() as db:
        assert db.scalar(select(StudyAnswer.ratings)) == {"difficulty": 3, "partner": 4}, "ratings stay"
        assert stored(server, ann_code).consent_version == "1", "the code and its record stay"
        purged = db.scalars(select(StudyEvent.payload).where(StudyEvent.kind == "purged")).all()
        assert [p["participants"] for p in purged] == [2]
    assert "personal data of 0 participant(s) deleted" in purge_cli(server), "nothing left to delete"

    # At a server's start: another study, due, purged before the server takes a request.
    files.save(study("second", practice_maze=None))
    cat, _ = join(server, "second", real_name="Cat Real")
    server.stop()
    later = study("second", practice_maze=None, purge_after_days=0)
    files.save(later.model_copy(update={"closed_at": datetime.now(UTC) - timedelta(seconds=1)}))
    again = start_server(settings=server.settings)
    with again.services.db() as db:
        names = db.scalars(select(StudyParticipant.real_name).where(StudyParticipant.study == "second")).all()
        assert names == [None]


def test_withdrawal_and_logout_clear_the_site_data(server):
    StudyFiles.of(server.settings.data_dir).save(study("pilot", practice_maze=None))
    ann, _ = join(server, "pilot")
    gone = ann.post("/study/pilot/withdraw", data={"confirm": "yes"})
    assert gone.headers["clear-site-data"] == '"cache", "cookies", "storage"'
    eve = experimenter_client(server.services, server.url)
    out = eve.post("/logout", follow_redirects=False)
    assert out.status_code == 303 and out.headers["clear-site-data"] == '"cache", "cookies", "storage"'


def set_cookies(response) -> dict[str, str]:
    """The response's Set-Cookie lines: name -> the whole line."""
    return {line.split("=", 1)[0]: line for line in response.headers.get_list("set-cookie")}


@pytest.mark.settings(trusted_proxies=["127.0.0.1"])
def test_over_tls_the_cookies_are_host_prefixed_and_secure(server):
    """Behind a TLS proxy (X-Forwarded-Proto: https from a trusted address), every cookie the
    server sets is __Host- (Secure, Path=/, no Domain) and only that name is read back. (The
    client's jar would not send Secure cookies to this http:// address: they are sent by hand.)"""
    StudyFiles.of(server.settings.data_dir).save(study("pilot", practice_maze=None))
    origin = server.url.replace("http://", "https://")
    tls = httpx.Client(base_url=server.url, headers={"X-Forwarded-Proto": "https", "Origin": origin}, timeout=60)
    page = tls.get("/study/pilot")
    browser_cookie = set_cookies(page)["__Host-robotslang_browser"]
    assert "Secure" in browser_cookie and "Path=/;" in browser_cookie and "Domain" not in browser_cookie
    jar = f"__Host-robotslang_browser={browser_cookie.split(';')[0].split('=', 1)[1]}"
    agreed = tls.post(
        "/study/pilot/consent",
        data={"choice": "agree", "consent_version": "1", "csrf_token": page_csrf_token(page.text)},
        headers={"Cookie": jar},
    )
    study_pass = set_cookies(agreed)["__Host-robotslang_study"]
    assert "Path=/;" in study_pass and "secure" in study_pass.lower() and "Domain" not in study_pass
    value = study_pass.split(";")[0].split("=", 1)[1]
    hosted = tls.get("/study/pilot/code", headers={"Cookie": f"{jar}; __Host-robotslang_study={value}"})
    assert hosted.status_code == 200, "the __Host- pass is read back"
    unprefixed = tls.get("/study/pilot/code", headers={"Cookie": f"{jar}; robotslang_study={value}"})
    assert unprefixed.status_code == 403, "over TLS the plain name is not read"
    plain = httpx.Client(base_url=server.url, headers={"Origin": server.url}, timeout=60)
    assert "robotslang_browser" in set_cookies(plain.get("/")), "over http: plain names"
    assert plain.get("/study/pilot/code", headers={"Cookie": f"robotslang_study={value}"}).status_code == 200

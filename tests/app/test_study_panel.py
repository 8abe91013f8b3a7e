"""A study recruited on a panel (Prolific's link parameters), against a real server: the panel's
identifiers a link carries are stored with the pseudonym, shown on no public page and cleaned from
the address bar at once; each way's end page sends the participant on to the panel's completion
address with that outcome's code; and the experimenter's roster (export and download) has one row
per participant with the panel's identifiers, the outcome, its code and the minutes to pay."""

from __future__ import annotations

import csv
import html
import io
import json
from datetime import UTC, datetime, timedelta

from sqlalchemy import select
from typer.testing import CliRunner

from app.cli import root
from app.db.models import Participant, StudyParticipant
from app.study.config import StudyFiles
from tests.app.live import browser, experimenter_client
from tests.app.test_study import end, join, poll
from tests.app.test_study_paths import CODES, finish, study

PROLIFIC = "https://app.prolific.com/submissions/complete?cc={code}"


def arrive(server, pid: str, session: str):
    """A stranger opens the panel's study link: it is answered with the clean address, then they
    consent as anyone does."""
    client = browser(server.url)
    link = f"/study/pilot?PROLIFIC_PID={pid}&STUDY_ID=ST-77&SESSION_ID={session}"
    first = client.get(link, follow_redirects=False)
    assert first.status_code == 303 and first.headers["location"] == "/study/pilot", "the address bar cleaned"
    assert pid not in first.text
    client, code = join(server, "pilot", client=client)
    assert "robotslang_panel" not in client.cookies, "kept with the participant now, not in the browser"
    return client, code


def stored(server, code: str) -> StudyParticipant:
    with server.services.db() as db:
        return db.execute(
            select(StudyParticipant)
            .join(Participant, Participant.id == StudyParticipant.participant_id)
            .where(Participant.name == code)
        ).scalar_one()


def backdate(server, code: str, waiting_min: float, in_study_min: float) -> None:
    """Fake time: the participant now waiting in the lobby began this wait and consented so long ago."""
    with server.services.db.begin() as db:
        row = db.get(StudyParticipant, stored(server, code).id)
        assert row is not None and row.lobby_since is not None
        now = datetime.now(UTC)
        row.lobby_since, row.created_at = now - timedelta(minutes=waiting_min), now - timedelta(minutes=in_study_min)


def onward(page: str) -> tuple[str, str]:
    """The end page's link on (to the panel, with the code) and the countdown's seconds before
    its script follows it (the browser test sees it followed)."""
    link = page.split('id="completion-link" href="')[1].split(">")[0]
    return html.unescape(link.split('"')[0]), link.split('data-after-s="')[1].split('"')[0]


def test_a_panel_link_is_stored_with_the_pseudonym_on_no_public_page_and_each_end_goes_to_the_panel(server):
    StudyFiles.of(server.settings.data_dir).save(
        study(
            "pilot",
            practice_maze=None,
            trials_per_participant=1,
            outcome_codes=CODES,
            panel={"completion_url": PROLIFIC},
        )
    )
    ann, ann_code = arrive(server, "PID-ANN", "SE-1")
    bob, _ = arrive(server, "PID-BOB", "SE-2")
    row = stored(server, ann_code)
    assert (row.panel_participant, row.panel_study, row.panel_session) == ("PID-ANN", "ST-77", "SE-1")

    assert poll(ann)["state"] == "waiting"
    seat = poll(bob)
    eve = experimenter_client(server.services, server.url)
    end(server, eve)
    done = finish(ann)  # the plan's one trial played
    assert done.url.path == "/study/pilot/done", "the end page's own address carries no identifiers"
    assert onward(done.text) == (PROLIFIC.format(code="DONE-PILOT"), "10")

    pages = [ann.get(p).text for p in ("/study/pilot/me", "/study/pilot/code", "/study/pilot/instructions")]
    pages += [done.text, ann.get("/leaderboard?study=pilot").text, bob.get(seat["link"]).text]
    pages += [bob.get("/study/pilot/lobby").text, browser(server.url).get("/study/pilot").text]
    for page in pages:
        assert not any(secret in page for secret in ("PID-ANN", "PID-BOB", "ST-77", "SE-1", "SE-2"))

    cat, _ = arrive(server, "PID-CAT", "SE-3")
    gone = cat.post("/study/pilot/withdraw", data={"confirm": "yes"}).text
    assert onward(gone) == (PROLIFIC.format(code="WITHDREW-3"), "10")

    dan, dan_code = arrive(server, "PID-DAN", "SE-4")
    assert poll(dan)["state"] == "waiting"
    backdate(server, dan_code, waiting_min=12, in_study_min=20)  # Dan has waited 12 minutes, 20 since consenting
    state = poll(dan)
    assert state["state"] == "timed_out" and state["outcome"] == "no_partner"
    assert onward(dan.get(state["next"]).text) == (PROLIFIC.format(code="NOPAIR-2"), "10")

    # A returning browser's link opened again is cleaned too, and keeps the identifiers stored;
    # one who came by the plain link and then by the panel's has theirs stored then.
    again = ann.get("/study/pilot?PROLIFIC_PID=PID-OTHER&STUDY_ID=X&SESSION_ID=Y", follow_redirects=False)
    assert again.status_code == 303 and again.headers["location"] == "/study/pilot"
    assert stored(server, ann_code).panel_participant == "PID-ANN"
    fay, fay_code = join(server, "pilot")
    assert stored(server, fay_code).panel_participant is None
    fay.get("/study/pilot?PROLIFIC_PID=PID-FAY&STUDY_ID=ST-77&SESSION_ID=SE-5")
    row = stored(server, fay_code)
    assert (row.panel_participant, row.panel_study, row.panel_session) == ("PID-FAY", "ST-77", "SE-5")


def test_the_roster_has_one_row_per_participant_with_the_panels_ids_outcome_code_and_minutes(server, tmp_path):
    StudyFiles.of(server.settings.data_dir).save(
        study(
            "pilot",
            practice_maze=None,
            trials_per_participant=1,
            outcome_codes=CODES,
            panel={"completion_url": PROLIFIC},
        )
    )
    ann, ann_code = arrive(server, "PID-ANN", "SE-1")
    bob, bob_code = arrive(server, "PID-BOB", "SE-2")
    assert poll(ann)["state"] == "waiting"
    backdate(server, ann_code, waiting_min=7, in_study_min=9)  # Ann has waited 7 minutes when Bob comes
    assert poll(bob)["state"] == "seated"
    eve = experimenter_client(server.services, server.url)
    end(server, eve)
    assert finish(ann).url.path == "/study/pilot/done"
    cat, cat_code = arrive(server, "PID-CAT", "SE-3")
    cat.post("/study/pilot/withdraw", data={"confirm": "yes"})
    dan, dan_code = arrive(server, "PID-DAN", "SE-4")  # still waiting at the export: counted to his last ask
    assert poll(dan)["state"] == "waiting"

    download = eve.get("/experimenter/studies/pilot/participants.csv")
    assert download.status_code == 200 and download.headers["content-type"].startswith("text/csv")
    env = {"ROBOTSLANG_DATA_DIR": str(server.settings.data_dir), "ROBOTSLANG_SECRET_KEY": "test-secret"}
    out = tmp_path / "export"
    made = CliRunner().invoke(
        root, ["export", "all", "--study", "pilot", "--include-aborted", "--format", "ndh", "--out", str(out)], env=env
    )
    assert made.exit_code == 0, made.output
    for text in (download.text, (out / "participants.csv").read_text()):
        rows = {r["participant"]: r for r in csv.DictReader(io.StringIO(text))}
        assert set(rows) == {ann_code, bob_code, cat_code, dan_code}, "one row per participant"
        ann_row = rows[ann_code]
        assert (ann_row["panel_participant"], ann_row["panel_study"], ann_row["panel_session"]) == (
            "PID-ANN",
            "ST-77",
            "SE-1",
        )
        assert (ann_row["outcome"], ann_row["completion_code"]) == ("completed", "DONE-PILOT")
        assert abs(float(ann_row["minutes_in_lobby"]) - 7.0) < 0.2, "her wait, to the pairing"
        assert abs(float(ann_row["minutes_in_study"]) - 9.0) < 0.3, "consent to the end of her way"
        assert float(rows[bob_code]["minutes_in_lobby"]) < 0.2, "Bob was paired on his first ask"
        assert (rows[cat_code]["outcome"], rows[cat_code]["completion_code"]) == ("withdrew", "WITHDREW-3")
        assert rows[cat_code]["panel_participant"] == "PID-CAT", "kept for paying after a withdrawal"
        assert (rows[dan_code]["outcome"], rows[dan_code]["completion_code"]) == ("", "")
    assert json.dumps(rows).count("PID-") == 4


def test_a_panel_whose_completion_address_has_no_code_is_refused_with_the_reason(server):
    files = StudyFiles.of(server.settings.data_dir)
    files.save(study("pilot", practice_maze=None))
    eve = experimenter_client(server.services, server.url)
    bad = study("pilot", practice_maze=None).model_dump(mode="json")
    bad["panel"] = {"completion_url": "https://app.prolific.com/submissions/complete"}
    page = eve.post("/experimenter/studies/pilot", data={"config_json": json.dumps(bad)})
    assert page.status_code == 400 and "needs {code} where the outcome" in html.unescape(page.text)
    assert files.load("pilot").panel is None and files.load("pilot").version == 1, "the file unchanged"

"""A study's questionnaire answers read back, and one definition of a move: two strangers play a
study trial to the end through the real server (one move request refused on the way), answer its
questionnaire under two versions of the study, and the experimenter reads the answers on the study
page, in `export all --study NAME` and in `report study`, whose moves and score are the
leaderboard's."""

from __future__ import annotations

import asyncio
import csv
import html
import io
import json
import re

import pytest
from typer.testing import CliRunner

from app.cli import root
from app.db.models import Trial
from app.study.config import StudyFiles, template
from sim.trial.state import fold
from tests.app.live import TrialHandle, browser, experimenter_client
from tests.app.test_study import answers, join, study_trial
from tests.app.trial_play import claim_and_decide, drive_to_target, start_trial

PENALTY_S = 2.5  # the study's own, not the server's 1.0: the report and the leaderboard both use it


async def play_to_the_end(server, trial: TrialHandle) -> None:
    """The Driver's page opens first and asks for a move before the trial starts (refused: it
    waits for the Commander); then both play all three targets."""
    services = server.services
    async with trial.seat("driver") as driver:
        await driver.send("move", action="forward", move_id="early")
        assert (await driver.moved("early"))["outcome"] == "refused"
        async with trial.seat("commander") as commander:
            await start_trial(commander, driver)
            await commander.send("localize", x=1.2, y=1.0, heading=0.5)
            await driver.event("phase", phase="navigating", target_index=0)
            for _ in range(3):
                await drive_to_target(services, trial.id, driver)
                await claim_and_decide(commander, driver, confirm=True)
            await commander.event("phase", phase="finished")


def test_answers_on_the_study_page_in_the_export_and_the_report_with_the_leaderboards_moves(server, tmp_path, trials):
    files = StudyFiles.of(server.settings.data_dir)
    files.save(template("pilot").model_copy(update={"practice_maze": None, "move_penalty_s": PENALTY_S}))
    (ann, ann_code), (bob, bob_code) = join(server, "pilot"), join(server, "pilot")
    trial_id = study_trial(server, "pilot", (ann_code, bob_code))  # Ann commands, Bob drives
    asyncio.run(play_to_the_end(server, trials.of(trial_id)))

    url = f"/study/pilot/trials/{trial_id}/questionnaire"
    assert (
        ann.post(url, data=answers(ann_code, difficulty="2", partner="5", comments="a fine driver")).status_code == 200
    )
    # The experimenter rewords an item between the two answers: Bob answers under version 2.
    eve = experimenter_client(server.services, server.url)
    v1 = files.load("pilot")
    reworded = [
        q.model_copy(update={"prompt": "How hard was it? (1-5)"}) if q.id == "difficulty" else q
        for q in v1.questionnaire
    ]
    files.save(v1.model_copy(update={"questionnaire": reworded}))
    assert bob.post(url, data=answers(bob_code, difficulty="4", partner="3")).status_code == 200

    page = eve.get("/experimenter/studies/pilot").text
    for table in ("answers-participant", "answers-trial"):
        rows = page.split(f'id="{table}"')[1].split("</table>")[0]
        ann_row = rows.split(f'data-code="{ann_code}"')[1].split("</tr>")[0]
        bob_row = rows.split(f'data-code="{bob_code}"')[1].split("</tr>")[0]
        assert "<td>commander</td>" in ann_row and f"{bob_code} (driver)" in ann_row, "the partner's seat named"
        assert '<td data-item="partner">5</td>' in ann_row and "a fine driver" in ann_row
        assert "<td>driver</td>" in bob_row and f"{ann_code} (commander)" in bob_row
        assert '<td data-item="difficulty">4</td>' in bob_row and "<td>2</td>" in bob_row, "asked under version 2"

    env = {"ROBOTSLANG_DATA_DIR": str(server.settings.data_dir), "ROBOTSLANG_SECRET_KEY": "test-secret"}
    out = tmp_path / "ndh"
    made = CliRunner().invoke(
        root, ["export", "all", "--study", "pilot", "--format", "ndh", "--out", str(out)], env=env
    )
    assert made.exit_code == 0, made.output
    exported = json.loads((out / "questionnaires.json").read_text())
    prompts = {v: {q["id"]: q["prompt"] for q in qs} for v, qs in exported["questionnaires"].items()}
    assert (
        prompts["1"]["difficulty"] == v1.questionnaire[0].prompt
        and prompts["2"]["difficulty"] == "How hard was it? (1-5)"
    )
    by_code = {a["participant"]: a for a in exported["answers"]}
    assert by_code[ann_code] == {
        "trial_id": trial_id,
        "trial_phase": "finished",
        "participant": ann_code,
        "seat": "commander",
        "partner": bob_code,
        "partner_seat": "driver",
        "study_version": 1,
        "ratings": {"difficulty": 2, "partner": 5},
        "free_text": {"comments": "a fine driver"},
    }
    assert by_code[bob_code]["study_version"] == 2 and by_code[bob_code]["free_text"] == {}
    table = list(csv.DictReader(io.StringIO((out / "questionnaires.csv").read_text())))
    assert [
        (
            r["participant"],
            r["seat"],
            r["partner_seat"],
            r["study_version"],
            r["difficulty"],
            r["partner"],
            r["comments"],
        )
        for r in table
    ] == sorted(
        [
            (ann_code, "commander", "driver", "1", "2", "5", "a fine driver"),
            (bob_code, "driver", "commander", "2", "4", "3", ""),
        ]
    )

    report = tmp_path / "report"
    made = CliRunner().invoke(root, ["report", "study", "--study", "pilot", "--out", str(report)], env=env)
    assert made.exit_code == 0, made.output
    numbers = json.loads((report / "study.json").read_text())
    items = numbers["questionnaire"]["items"]
    assert set(items) == {"difficulty", "partner"}, "ratings only: free text is not a distribution"
    assert items["difficulty"]["by_seat"]["commander"] == {
        "n": 1,
        "counts": {"1": 0, "2": 1, "3": 0, "4": 0, "5": 0},
        "mean": 2.0,
    }
    assert items["partner"]["by_seat"]["driver"]["counts"]["3"] == 1 and items["partner"]["by_seat"]["driver"]["n"] == 1
    png = (report / "questionnaire.png").read_bytes()
    assert png.startswith(b"\x89PNG") and len(png) > 5000
    assert "![questionnaire ratings](questionnaire.png)" in (report / "study.md").read_text()

    # One definition of a move: the executed ones, as the leaderboard counts them; the refused request apart.
    state = fold(server.services.log.load(trial_id))
    assert state.refused == 1 and state.moves > 0
    with server.services.db() as db:
        row = db.get(Trial, trial_id)
    assert row.moves == state.moves, "the leaderboard's count"
    trial = numbers["trials"][str(trial_id)]
    assert trial["moves"] == state.moves and trial["refused_moves"] == 1
    assert numbers["moves"]["mean"] == state.moves and numbers["refused_moves"]["mean"] == 1
    assert trial["score"] == pytest.approx(row.active_s + PENALTY_S * state.moves)
    board = html.unescape(browser(server.url).get("/leaderboard?study=pilot").text)
    best = re.search(r'<td class="team">[^<]*</td><td class="driver">[^<]*</td><td>1</td>\s*<td>([\d.]+)</td>', board)
    assert best is not None, board[:2000]
    assert float(best.group(1)) == pytest.approx(trial["score"], abs=0.05), "the leaderboard's score"
    assert numbers["leaderboard"][f"{ann_code}+{bob_code}"]["best"] == trial["score"]

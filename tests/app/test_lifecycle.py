"""The experimenter's lifecycle over a real server: one live trial per participant, deleting
only what nothing uses (each refusal says why), excluding a trial from the leaderboard and
exports with a reason (its log kept, the replay says so), and exporting aborted trials."""

from __future__ import annotations

import asyncio
import html
import json
import os
import subprocess
import sys

from app.db.models import Participant, Robot, Team, Trial
from app.demo.runner import Demo
from app.rover.records import create_robot
from bench.live import REPO
from tests.app.live import experimenter_client, open_seats
from tests.app.trial_play import claim_and_decide, drive_to_target, start_trial


def export(settings, *args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "ROBOTSLANG_DATA_DIR": str(settings.data_dir), "ROBOTSLANG_SECRET_KEY": "test-secret"}
    return subprocess.run(
        [sys.executable, "-c", "from app.cli import main; main()", "export", *args],
        env=env,
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=300,
    )


def test_only_what_nothing_uses_is_deleted_and_a_refusal_says_why(server, trials):
    services = server.services
    client = experimenter_client(services, server.url)
    trial = trials.new(team="Owls")  # members "Owls commander/driver"
    with services.db.begin() as db:
        loner = Participant(name="Loner")
        db.add(loner)
        rover, _ = create_robot(db, "rover-1")
        spare, _ = create_robot(db, "spare", role="overhead")
        db.flush()
        ids = {"loner": loner.id, "rover": rover.id, "spare": spare.id}
        owls = db.query(Team).filter_by(name="Owls").one()
        member = owls.member_a_id
    client.post(f"/experimenter/trials/{trial.id}/abort")
    client.post("/experimenter/trials", data={"team_id": owls.id, "backend": f"robot:{ids['rover']}"})
    rover_trial = trial.id + 1

    refused = client.delete(f"/experimenter/participants/{member}")
    assert refused.status_code == 409
    assert refused.json()["detail"] == "participant 'Owls commander' is a member of team 'Owls': delete the team first"
    refused = client.delete(f"/experimenter/teams/{owls.id}")
    assert refused.status_code == 409
    assert (
        refused.json()["detail"] == f"team 'Owls' has played trials ({trial.id}, {rover_trial}): exclude them instead"
    )
    refused = client.delete(f"/experimenter/robots/{ids['rover']}")
    assert refused.status_code == 409
    assert refused.json()["detail"] == f"robot 'rover-1' is the robot of trial {rover_trial}: its recordings name it"
    assert client.delete("/experimenter/participants/999").status_code == 409

    assert client.delete(f"/experimenter/participants/{ids['loner']}").json() == {"deleted": True}
    assert client.delete(f"/experimenter/robots/{ids['spare']}").json() == {"deleted": True}
    with services.db() as db:
        assert db.get(Participant, ids["loner"]) is None and db.get(Participant, member) is not None
        assert [r.name for r in db.query(Robot)] == ["rover-1"] and db.get(Team, owls.id) is not None
        assert [t.id for t in db.query(Trial).order_by(Trial.id)] == [trial.id, rover_trial]
    page = client.get("/experimenter").text
    assert "Loner" not in page and "spare" not in page


def test_a_participant_is_in_one_live_trial_at_a_time(server, trials):
    services = server.services
    client = experimenter_client(services, server.url)
    trial = trials.new(team="Owls")
    with services.db() as db:
        owls = db.query(Team).filter_by(name="Owls").one()
    page = html.unescape(client.post("/experimenter/trials", data={"team_id": owls.id}).text)
    assert f"team 'Owls': a member is in trial {trial.id}, which is waiting;" in page
    client.post(f"/experimenter/trials/{trial.id}/abort")
    client.post("/experimenter/trials", data={"team_id": owls.id})
    with services.db() as db:
        assert [t.phase for t in db.query(Trial).order_by(Trial.id)] == ["aborted", "waiting"]


def test_an_excluded_trial_leaves_the_leaderboard_and_exports_and_its_replay_says_why(settings, start_server, tmp_path):
    (done,) = asyncio.run(Demo(settings, seed=3, pace_s=0.0).run(1))
    assert done.phase == "finished"
    server = start_server()  # on the demo's database
    client = experimenter_client(server.services, server.url)
    team = f"demo team {1}"
    assert team in client.get("/leaderboard").text
    page = client.post(f"/experimenter/trials/{done.trial_id}/exclude", data={"reason": "  "}).text
    assert "give a reason for excluding the trial" in page
    reason = "the Driver's partner helped by phone"
    client.post(f"/experimenter/trials/{done.trial_id}/exclude", data={"reason": reason, "back": "replay"})
    assert team not in client.get("/leaderboard").text
    replay = html.unescape(client.get(f"/experimenter/trials/{done.trial_id}/replay").text)
    assert f"Excluded from the leaderboard and exports: {reason}" in replay
    log = client.get(f"/experimenter/trials/{done.trial_id}/replay.json").json()
    assert log["trial"]["excluded"] == reason and log["events"][-1]["kind"] == "phase"  # the log is kept
    assert f"(excluded: {reason})" in html.unescape(client.get("/experimenter").text)
    server.stop()
    result = export(settings, "all", "--format", "ndh", "--out", str(tmp_path / "ndh"))
    assert result.returncode == 1 and "no finished trials (not excluded)" in result.stderr


def test_export_all_includes_aborted_trials_with_the_targets_they_confirmed(server, settings, tmp_path, trials):
    services = server.services
    client = experimenter_client(services, server.url)
    trial = trials.new(targets=("jar", "mug", "paddle"), team="Owls")

    async def first_target_then_abort() -> None:
        async with (
            trial.seat("commander") as commander,
            trial.seat("driver") as driver,
        ):
            await start_trial(commander, driver)
            await commander.send("localize", x=1.2, y=1.0, heading=0.5)
            await driver.event("phase", phase="navigating", target_index=0)
            await drive_to_target(services, trial.id, driver)
            await claim_and_decide(commander, driver, confirm=True)
            await asyncio.to_thread(client.post, f"/experimenter/trials/{trial.id}/abort")
            await commander.event("phase", phase="aborted")

    asyncio.run(first_target_then_abort())
    out = tmp_path / "ndh"
    result = export(settings, "all", "--format", "ndh", "--out", str(out))
    assert result.returncode == 1 and "no finished trials" in result.stderr
    result = export(settings, "all", "--format", "ndh", "--out", str(out), "--include-aborted")
    assert result.returncode == 0, result.stderr
    instances = [
        i
        for split in ("train", "val_seen", "test")
        for i in json.loads((out / "NDH-data" / f"{split}.json").read_text())
    ]
    assert [i["target"] for i in instances] == ["jar"], "the confirmed target of the aborted trial is exported"
    with_seats = {"commander": "participant 1", "driver": "participant 2"}  # ids: names stay in the database
    assert instances[0]["seats"] == with_seats


def test_an_aborted_trial_restarts_with_the_same_seats_on_a_layout_the_team_has_not_seen(server, trial):
    client = experimenter_client(server.services, server.url)
    refused = html.unescape(client.post(f"/experimenter/trials/{trial.id}/restart").text)
    assert f"trial {trial.id} is waiting: only an aborted trial is restarted" in refused
    with server.services.db.begin() as db:
        db.get(Trial, trial.id).study = "pilot"
    open_seats(server, trial.id, "commander", "driver")  # both loaded their pages: the map was seen
    client.post(f"/experimenter/trials/{trial.id}/abort", data={"reason": "the Driver's browser crashed"})
    row = client.get("/experimenter").text
    assert f'action="/experimenter/trials/{trial.id}/restart"' in row
    client.post(f"/experimenter/trials/{trial.id}/restart")
    layouts = server.services.mazes.layouts()
    with server.services.db() as db:
        old = db.get(Trial, trial.id)
        (new,) = db.query(Trial).filter(Trial.id > trial.id).all()
    assert (new.team_id, new.targets, new.backend, new.driver, new.commander) == (
        old.team_id,
        old.targets,
        old.backend,
        old.driver,
        old.commander,
    )
    assert (new.commander_id, new.driver_id, new.study, new.phase) == (
        old.commander_id,
        old.driver_id,
        "pilot",
        "waiting",
    )
    assert layouts[new.maze] != layouts[old.maze], "the aborted layout counts as seen"
    page = html.unescape(client.post(f"/experimenter/trials/{new.id}/restart").text)
    assert f"trial {new.id} is waiting: only an aborted trial is restarted" in page


def test_a_trial_whose_commander_never_loaded_the_map_restarts_on_the_same_layout(server, trial):
    client = experimenter_client(server.services, server.url)
    open_seats(server, trial.id, "driver")  # the Commander's page never opened
    client.post(f"/experimenter/trials/{trial.id}/abort")
    client.post(f"/experimenter/trials/{trial.id}/restart")
    with server.services.db() as db:
        old = db.get(Trial, trial.id)
        (new,) = db.query(Trial).filter(Trial.id > trial.id).all()
    assert new.maze == old.maze and new.phase == "waiting", "nobody saw the map: the layout is still unseen"
    open_seats(server, new.id, "commander", "driver")
    client.post(f"/experimenter/trials/{new.id}/abort")
    client.post(f"/experimenter/trials/{new.id}/restart")
    with server.services.db() as db:
        newest = db.query(Trial).filter(Trial.id > new.id).one()
    layouts = server.services.mazes.layouts()
    assert layouts[newest.maze] != layouts[old.maze], "once the Commander loaded it, the layout counts as seen"


def test_the_experimenters_notes_stay_on_the_experimenters_pages(settings, start_server, tmp_path, trials):
    (done,) = asyncio.run(Demo(settings, seed=4, pace_s=0.0).run(1))
    notes = "Driver asked twice what a paddle is; lab door slammed at 3:10"
    server = start_server()  # on the demo's database
    client = experimenter_client(server.services, server.url)
    client.post(f"/experimenter/trials/{done.trial_id}/notes", data={"notes": notes, "back": "replay"})
    assert notes in html.unescape(client.get(f"/experimenter/trials/{done.trial_id}").text)
    assert notes in html.unescape(client.get(f"/experimenter/trials/{done.trial_id}/replay").text)
    assert notes not in html.unescape(client.get("/leaderboard").text)
    seat = trials.of(done.trial_id, on=server).tokens["commander"]
    assert notes not in html.unescape(client.get(f"/play/{seat}").text)
    long = client.post(f"/experimenter/trials/{done.trial_id}/notes", data={"notes": "x" * 10_001})
    assert long.status_code == 422
    assert notes in html.unescape(client.get(f"/experimenter/trials/{done.trial_id}").text), "kept"
    server.stop()
    for fmt, out in (("ndh", tmp_path / "ndh"), ("mcap", tmp_path / "mcap")):
        assert export(settings, "all", "--format", fmt, "--out", str(out)).returncode == 0
        assert not any(notes.encode() in f.read_bytes() for f in out.rglob("*") if f.is_file()), fmt

"""`robotslang annotate assign`, `report agreement` and `report study` as processes on a real
SQLite database whose trials were played through the real trial core, and the LDH export of an
annotated trial (its adjudicated cut)."""

from __future__ import annotations

import asyncio
import html
import json
import statistics

import pyarrow.parquet as pq
import pytest
from mcap.reader import make_reader
from sqlalchemy import select

from app.annotation.events import Adjudicated, CutMarked, Submitted, Tagged
from app.annotation.log import AnnotationLog
from app.db.models import AnnotationAssignment, Experimenter, Team, Trial
from app.trial.setup import create_trial, suggest_maze
from sim.trial import events as ev
from sim.trial.state import trial_score
from tests.app.live import TrialHandle, Trials, cli, experimenter_client
from tests.app.trial_play import claim_and_decide, drive_to_target, start_trial

pytestmark = pytest.mark.slow
STUDY = "pilot"


async def play(server, trial: TrialHandle, said: list[tuple[str, str]]) -> None:
    """The trial start to finish: the dialog `said` before the estimate, one message after it."""
    services = server.services
    async with (
        trial.seat("commander") as commander,
        trial.seat("driver") as driver,
    ):
        seat = {"commander": commander, "driver": driver}
        await start_trial(commander, driver)
        for role, text in said:
            other = driver if role == "commander" else commander
            start = len(other.received)
            await seat[role].send("chat", text=text)
            await other.event("chat", text=text, start=start)
        await commander.send("localize", x=1.2, y=1.0, heading=0.5)
        await driver.event("phase", phase="navigating", target_index=0)
        await commander.send("chat", text="now find the first one")
        for _ in range(3):
            await drive_to_target(services, trial.id, driver)
            await claim_and_decide(commander, driver, confirm=True)
        await commander.event("phase", phase="finished")


DIALOGS = [
    [("commander", "what do you see"), ("driver", "a red wall ahead"), ("commander", "turn left twice")],
    [
        ("commander", "hello"),
        ("driver", "blue wall and a mug"),
        ("commander", "you are in the corner"),
        ("driver", "ok"),
    ],
    [("driver", "i see nothing but green"), ("commander", "turn around slowly please")],
]


@pytest.fixture(scope="module")
def study(start_module_server):
    """Three finished trials of study `pilot` (two by team Owls, one by Larks), played for real."""
    server = start_module_server()
    trials = Trials(lambda: server)
    settings = server.settings
    services = server.services
    first = trials.new(team="Owls")
    asyncio.run(play(server, first, DIALOGS[0]))
    layouts = services.mazes.layouts()
    with services.db.begin() as db:
        owls = db.scalar(select(Team).where(Team.name == "Owls"))
        second = create_trial(
            db,
            team_id=owls.id,
            maze=suggest_maze(db, owls, layouts),
            targets=["jar", "mug", "paddle"],
            backend="sim",
            driver="human",
            commander_id=owls.member_a_id,
            layouts=layouts,
            now_ns=services.clock.now_ns(),
        ).id
    asyncio.run(play(server, trials.of(second), DIALOGS[1]))
    third = trials.new(team="Larks")
    asyncio.run(play(server, third, DIALOGS[2]))
    ids = [first.id, second, third.id]
    with services.db.begin() as db:
        for trial_id in ids:
            db.get(Trial, trial_id).study = STUDY
    logs = {i: services.log.load(i) for i in ids}
    server.stop()  # the tests' commands have the database to themselves
    env = {"ROBOTSLANG_DATA_DIR": str(settings.data_dir), "ROBOTSLANG_SECRET_KEY": "test-secret"}
    return settings, env, ids, logs


def test_assign_agreement_and_the_adjudicated_cut_in_the_ldh_export(study, tmp_path, start_server):
    settings, env, ids, logs = study
    for name in ("ann", "bob"):
        made = cli("admin", "create", name, "--role", "annotator", "--password", "annotate well", env=env)
        assert made.returncode == 0 and f"annotator '{name}' created" in made.stdout, made.stderr
    assigned = cli(
        "annotate",
        "assign",
        "--study",
        STUDY,
        "--annotator",
        "ann",
        "--annotator",
        "bob",
        "--share",
        "0.67",
        "--seed",
        "3",
        env=env,
    )
    assert assigned.returncode == 0, assigned.stderr
    assert "2 trials for two annotators, 1 for one" in assigned.stdout
    again = cli("annotate", "assign", "--study", STUDY, "--annotator", "ann", "--annotator", "bob", env=env)
    assert "0 trials for two annotators, 0 for one" in again.stdout  # assigned once

    from app.db.engine import open_database

    sessions = open_database(settings)
    with sessions() as db:
        account = {n: i for i, n in db.execute(select(Experimenter.id, Experimenter.name))}
        queues = {}
        for trial_id, annotator in db.execute(select(AnnotationAssignment.trial_id, AnnotationAssignment.annotator_id)):
            queues.setdefault(trial_id, []).append(annotator)
    double = sorted(t for t, who in queues.items() if len(who) == 2)
    (single,) = [t for t, who in queues.items() if len(who) == 1]
    assert len(double) == 2 and sorted(queues) == sorted(ids)
    log = AnnotationLog(sessions)
    d1, d2 = double
    marks = {  # (annotator, trial): (cut, tags)
        ("ann", d1): (2, {"needs_history": [1]}),
        ("bob", d1): (3, {"needs_history": [1, 2]}),
        ("ann", d2): (1, {"needs_history": [2], "communication_repair": [2]}),
        ("bob", d2): (1, {"needs_history": [2]}),
        (None, single): (2, {"surrender_control": [1]}),
    }
    for (name, trial_id), (cut, tags) in marks.items():
        who = account[name] if name else queues[trial_id][0]
        log.append(trial_id, who, CutMarked(message=cut), 1)
        for tag, messages in tags.items():
            log.append(trial_id, who, Tagged(tag=tag, messages=messages), 2)
        log.append(trial_id, who, Submitted(), 3)

    report = cli("report", "agreement", "--study", STUDY, "--json", env=env)
    assert report.returncode == 0, report.stderr
    result = json.loads(report.stdout)
    # By hand: needs_history yes/yes twice: p_e = 1, undefined; communication_repair ann yes on d2 only,
    # bob never: p_o = 1/2, p_e = 1/2 * 0 + 1/2 * 1 = 1/2, kappa = 0.
    assert result["double_annotated_trials"] == 2
    assert result["kappa"]["needs_history"] is None and result["kappa"]["communication_repair"] == 0.0
    assert result["cut_distance"]["per_trial"] == {str(d1): 1, str(d2): 0} and result["cut_distance"]["mean"] == 0.5
    assert result["disagreements"] == [
        {"trial": d1, "item": "cut", "values": {"ann": 2, "bob": 3}, "adjudicated": None},
        {"trial": d2, "item": "communication_repair", "values": {"ann": True, "bob": False}, "adjudicated": None},
    ]
    printed = cli("report", "agreement", "--study", STUDY, env=env).stdout
    assert "kappa Communication Repair: 0.000" in printed and "mean 0.50 messages" in printed
    # A tag's answers read as yes/no, as the page and its adjudication put them.
    assert f"disagreement trial {d2} communication_repair: ann: yes; bob: no (adjudicated: —)" in printed

    server = start_server(settings)  # the experimenter's agreement page, and adjudication on it
    client = experimenter_client(server.services, server.url)
    page = html.unescape(client.get(f"/experimenter/annotation?study={STUDY}").text)
    assert "2 trials annotated by two annotators." in page and "mean distance 0.50 messages" in page
    assert '<tr data-tag="communication_repair"><td>Communication Repair</td><td class="k">0.000</td>' in page
    assert f'data-trial="{d1}" data-item="cut"' in page
    assert "ann: yes; bob: no" in page, "a tag's answers read as the yes/no its adjudication offers"
    decided = client.post(
        "/experimenter/annotation/adjudicate", data={"trial_id": d1, "item": "cut", "value": "3", "study": STUDY}
    )
    assert decided.status_code == 200 and "ann: 2; bob: 3" in html.unescape(decided.text)
    decided = client.post(
        "/experimenter/annotation/adjudicate",
        data={"trial_id": d2, "item": "communication_repair", "value": "no", "study": STUDY},
    )
    assert '<td class="adjudicated">no</td>' in decided.text and "True" not in decided.text
    unpaired = html.unescape(client.get("/experimenter/annotation?study=nobody-twice").text)
    assert "No trial of this study has been submitted by two annotators yet" in unpaired
    assert "n/a" not in unpaired and 'id="kappa"' not in unpaired
    server.stop()
    eve = AnnotationLog(sessions).records(d1)[-1]
    assert eve.event == Adjudicated(item="cut", value=3) and eve.annotator_id not in (account["ann"], account["bob"])
    result = json.loads(cli("report", "agreement", "--study", STUDY, "--json", env=env).stdout)
    assert result["disagreements"][0]["adjudicated"] == 3 and result["disagreements"][0]["values"] == {
        "ann": 2,
        "bob": 3,
    }

    out = tmp_path / "ndh"
    exported = cli("export", "all", "--format", "ndh", "--out", str(out), env=env)
    assert exported.returncode == 0, exported.stderr
    ldh = {
        int(i["trial_id"]): i
        for s in ("train", "val_seen", "test")
        for i in json.loads((out / "LDH-data" / f"{s}.json").read_text())
    }
    chats = {t: [e.payload["text"] for e in logs[t] if e.is_(ev.Chat)] for t in ids}
    assert ldh[d1]["localization_source"] == "adjudicated" and ldh[d1]["localized_after_message"] == 3
    assert [m["message"] for m in ldh[d1]["dialog_history"]] == chats[d1][:3]
    assert ldh[d2]["localization_source"] == "annotation" and len(ldh[d2]["dialog_history"]) == 1
    assert ldh[d2]["tags"] == {"needs_history": [2]}  # the disputed tag is not carried until adjudicated
    mcap = tmp_path / "d1.mcap"
    assert cli("export", str(d1), "--format", "mcap", "--out", str(mcap), env=env).returncode == 0
    with mcap.open("rb") as f:
        metadata = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    assert metadata["annotation"] == {
        "tags": json.dumps({"needs_history": [1, 2]}),
        "localized_after_message": "3",
        "localization_source": "adjudicated",
    }
    lerobot = tmp_path / "lerobot"
    made = cli("export", str(d1), "--format", "lerobot", "--out", str(lerobot), "--episode", "trial", env=env)
    assert made.returncode == 0, made.stderr
    (episode,) = pq.read_table(lerobot / "meta/episodes/chunk-000/file-000.parquet").to_pylist()
    assert json.loads(episode["annotation"]) == {
        "tags": {"needs_history": [1, 2]},
        "localized_after_message": 3,
        "localization_source": "adjudicated",
    }
    assert ldh[single]["localized_after_message"] == 2 and ldh[single]["tags"] == {"surrender_control": [1]}

    study_out = tmp_path / "report"
    made = cli("report", "study", "--study", STUDY, "--out", str(study_out), env=env)
    assert made.returncode == 0, made.stderr
    numbers = json.loads((study_out / "study.json").read_text())
    said = [len(chats[t]) for t in ids]
    words = [sum(len(m.split()) for m in chats[t]) for t in ids]
    assert numbers["messages_per_dialog"] == pytest.approx(statistics.fmean(said))
    assert numbers["words_per_dialog"] == pytest.approx(statistics.fmean(words))
    assert numbers["counts"]["trials"] == 3 and numbers["counts"]["teams"] == 2
    assert numbers["counts"]["participants"] == 4
    assert numbers["counts"]["trials_per_team"] == {"Larks": 1, "Owls": 2}
    by_role = {
        role: statistics.fmean([sum(e.payload["role"] == role for e in logs[t] if e.is_(ev.Chat)) for t in ids])
        for role in ("commander", "driver")
    }
    assert {r: v["messages_per_dialog"] for r, v in numbers["dialog"]["per_role"].items()} == pytest.approx(by_role)
    moves = [sum(e.is_(ev.MoveExecuted) for e in logs[t]) for t in ids]
    assert numbers["moves"]["mean"] == pytest.approx(statistics.fmean(moves))
    with sessions() as db:
        active = {t: db.get(Trial, t).active_s for t in ids}
    assert numbers["duration_minutes"]["mean"] == pytest.approx(statistics.fmean(active.values()) / 60)
    folds = numbers["folds"]
    assert sum(f["trials"] for f in folds.values()) == 3
    assert sum(f["ndh_instances"] for f in folds.values()) == 9 and sum(f["ldh_instances"] for f in folds.values()) == 3
    layouts = [set(f["by_layout"]) for f in folds.values()]
    assert not any(a & b for i, a in enumerate(layouts) for b in layouts[i + 1 :]), "no layout in two folds"
    phenomena = numbers["phenomena"]
    assert phenomena["annotated_dialogs"] == 3
    assert phenomena["tags"]["needs_history"]["frequency"] == pytest.approx(2 / 3)
    assert phenomena["tags"]["surrender_control"]["example"]["text"] == chats[single][0]
    assert phenomena["tags"]["perceptual_differences"]["dialogs"] == 0
    assert numbers["agreement"]["cut_distance"]["mean"] == 0.5
    penalty = settings.move_penalty_s
    owls = sorted(t for t in ids if t != ids[2])
    assert numbers["leaderboard"]["Owls"]["scores"] == pytest.approx(
        [trial_score(active[t], moves[ids.index(t)], penalty) for t in owls]
    )
    for png in ("dialog_lengths.png", "leaderboard.png", "learning_curves.png"):
        data = (study_out / png).read_bytes()
        assert data.startswith(b"\x89PNG") and len(data) > 5000, png
    markdown = (study_out / "study.md").read_text()
    assert "![learning curves](learning_curves.png)" in markdown and "Needs History" in markdown


def test_the_ndh_export_splits_the_study_by_layout_saves_the_split_and_reuses_it(study, tmp_path):
    settings, env, ids, logs = study
    folds = ["--study", STUDY, "--folds", "train:val:test=50:50:0", "--seed", "2"]
    out = tmp_path / "bench"
    made = cli("export", "all", "--format", "ndh", "--out", str(out), *folds, env=env)
    assert made.returncode == 0, made.stderr
    saved = json.loads((settings.data_dir / "folds" / f"{STUDY}.json").read_text())
    assert saved["shares"] == "train:val_seen:test=50:50:0" and saved["seed"] == 2
    assert sorted(saved["layouts"].values()) == ["train", "val_seen"], "two layouts, one in each fold"
    from app.mazes import Mazes

    layout_of = Mazes(settings).layouts()
    by_maze = json.loads((out / "splits.json").read_text())
    assert by_maze == {maze: saved["layouts"][layout_of[maze]] for maze in by_maze}
    for split in ("train", "val_seen"):
        instances = json.loads((out / "NDH-data" / f"{split}.json").read_text())
        assert instances and {by_maze[i["scan"].split("/")[1]] for i in instances} == {split}  # mazedata/<maze>/...

    again = cli("export", "all", "--format", "ndh", "--out", str(tmp_path / "again"), *folds, env=env)
    assert again.returncode == 0 and json.loads((tmp_path / "again" / "splits.json").read_text()) == by_maze
    # Without --folds the study's export keeps the study's split.
    plain = cli("export", "all", "--format", "ndh", "--out", str(tmp_path / "plain"), *folds[:2], env=env)
    assert plain.returncode == 0 and json.loads((tmp_path / "plain" / "splits.json").read_text()) == by_maze
    other = cli("export", "all", "--format", "ndh", "--out", str(tmp_path / "other"), *folds[:-1], "3", env=env)
    assert other.returncode == 1 and "--seed 2" in other.stderr, "a study is split once"
    refused = cli("export", "all", "--format", "mcap", "--out", str(tmp_path / "m"), *folds, env=env)
    assert refused.returncode == 1 and "--folds splits a study's NDH" in refused.stderr

    report = tmp_path / "report"
    assert cli("report", "study", "--study", STUDY, "--out", str(report), env=env).returncode == 0
    table = json.loads((report / "study.json").read_text())["folds"]
    assert {layout: fold for fold, f in table.items() for layout in f["by_layout"]} == saved["layouts"]

    # A study never split with --folds: its first export draws the default split and saves it, so
    # the next export (and the report) give each layout the same fold.
    (settings.data_dir / "folds" / f"{STUDY}.json").unlink()
    for n in (1, 2):
        made = cli("export", "all", "--format", "ndh", "--out", str(tmp_path / f"default{n}"), *folds[:2], env=env)
        assert made.returncode == 0, made.stderr
    first, second = (json.loads((tmp_path / f"default{n}" / "splits.json").read_text()) for n in (1, 2))
    default = json.loads((settings.data_dir / "folds" / f"{STUDY}.json").read_text())
    assert first == second == {maze: default["layouts"][layout_of[maze]] for maze in first}
    assert (default["shares"], default["seed"]) == ("train:val_seen:test=70:15:15", 0)

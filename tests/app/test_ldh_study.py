"""LDH human studies over HTTP against a real server: links that are forged, of another study or
a trial's seat open nothing; bad marks are refused and record nothing; the truth stays hidden
until a participant is done; answers survive a hard kill of the server process."""

from __future__ import annotations

import httpx
import pytest

from app.db.models import Experimenter, LDHStudyEvent
from app.main import build_services, ensure_experimenter
from app.security import StudyTokens, hash_password
from sim.tasks.benchmark import Benchmark
from sim.tasks.ldh import LDHInstance, Variant
from sim.tasks.ldh_eval import MazeContext, score
from tests.app.live import browser, log_in, page_csrf_token, platform_settings


def participant(base_url: str, link: str) -> tuple[httpx.Client, str]:
    """A participant's browser on their study page, with the page's CSRF token."""
    client = browser(base_url)
    page = client.get(link)
    assert page.status_code == 200, page.text[:300]
    client.headers["X-CSRF-Token"] = page_csrf_token(page.text)
    return client, page.text


def events(services, study_id: int) -> list[LDHStudyEvent]:
    with services.db() as db:
        return list(db.query(LDHStudyEvent).filter_by(study_id=study_id).order_by(LDHStudyEvent.seq))


@pytest.fixture
def settings(tmp_path, benchmark_path):
    return platform_settings(tmp_path, benchmark=benchmark_path)


@pytest.fixture
def server(server):
    """The platform on the benchmark, with an experimenter's account."""
    with server.services.db.begin() as db:
        db.add(Experimenter(name="eve", password_hash=hash_password("correct horse")))
    return server


def make_study(services, benchmark_path, n: int = 2, name: str = "pilot") -> int:
    return services.studies.create(1, name, str(benchmark_path), "val_seen", "prefix", n)


def link(server, study_id: int, participant_id: int) -> str:
    return f"/ldh/{StudyTokens(server.settings.signing_key()).issue(study_id, participant_id)}"


def test_forged_foreign_and_seat_links_open_nothing(server, benchmark_path, trials):
    services = server.services
    a, b = make_study(services, benchmark_path, name="A"), make_study(services, benchmark_path, name="B")
    studies = services.studies
    ann = studies.invite(a, "ann")
    bob = studies.invite(b, "bob")
    good, _ = participant(server.url, link(server, a, ann))
    before = len(events(services, a))
    crossed = link(server, a, bob)  # genuinely signed, but bob is not a participant of study A
    seat = f"/ldh/{trials.of(1).tokens['commander']}"  # a trial's join link: another salt
    forged = link(server, a, ann)[:-3] + "abc"
    for bad in (crossed, seat, forged):
        assert good.get(bad).status_code == 403
        assert good.get(bad + "/map/0.png").status_code == 403
        answer = good.post(bad + "/answers", json={"position": 0, "x": 1.0, "y": 1.0})
        assert answer.status_code == 403, answer.text
    assert len(events(services, a)) == before  # nothing recorded for any of them
    assert studies.answers(b) == []


def test_bad_marks_are_refused_and_the_truth_is_hidden_until_done(server, benchmark_path):
    services = server.services
    study_id = make_study(services, benchmark_path, n=2)
    studies = services.studies
    ann = studies.invite(study_id, "ann")
    client, page = participant(server.url, link(server, study_id, ann))
    truth = studies.instances(study_id)
    for inst in truth:  # the true positions appear nowhere on the page
        assert f"{inst.true_x:.2f}" not in page and f"{inst.true_x:.3f}" not in page
    url = link(server, study_id, ann) + "/answers"
    assert client.post(url, json={"position": 0, "x": 9.0, "y": 1.0}).status_code == 409  # off the map
    assert client.post(url, json={"position": 1, "x": 1.0, "y": 1.0}).status_code == 409  # not the one now
    assert client.post(url, json={"position": 0, "x": "a", "y": 1.0}).status_code == 422
    assert client.post(url, json={"position": 0, "x": 1.0, "y": 1.0, "td": 0}).status_code == 422  # no extras
    no_token = browser(server.url).post(url, json={"position": 0, "x": 1.0, "y": 1.0})
    assert no_token.status_code == 403  # CSRF: a page that did not come from this server
    assert studies.answers(study_id) == []

    first = client.post(url, json={"position": 0, "x": 1.0, "y": 1.0, "heading": 0.5})
    assert first.status_code == 200 and set(first.json()) == {"recorded", "next"}  # no score, no truth
    assert first.json()["next"] == 1
    assert client.post(url, json={"position": 0, "x": 1.2, "y": 1.0}).status_code == 409  # answered already
    page = client.get(link(server, study_id, ann)).text
    assert "2 of 2" in page and f"{truth[0].true_x:.2f}, {truth[0].true_y:.2f}" not in page
    client.post(url, json={"position": 1, "x": 0.5, "y": 0.5})
    done = client.get(link(server, study_id, ann)).text
    for inst in truth:  # done: now the truth is shown beside each mark
        assert f"{inst.true_x:.2f}, {inst.true_y:.2f}" in done

    bench = Benchmark(benchmark_path)
    for answer, inst in zip(studies.answers(study_id), truth):
        ctx = MazeContext(inst.run, bench.graph(inst.run, "benchmark"))
        expected = score(
            ctx,
            ctx.one_hot(ctx.node_at(answer.x, answer.y)),
            LDHInstance(inst.inst_idx, inst.run, inst.true_x, inst.true_y, None, (), Variant.PREFIX),
        )
        assert answer.td == pytest.approx(expected[0]) and answer.euclid == pytest.approx(expected[1])
    seqs = [e.seq for e in events(services, study_id)]
    stamps = [e.t_ns for e in events(services, study_id)]
    assert seqs == list(range(1, len(seqs) + 1)) and stamps == sorted(set(stamps))


def test_a_study_created_in_german_speaks_german_to_its_participant(server, benchmark_path):
    eve = log_in(server.url, "eve", "correct horse")
    token = page_csrf_token(eve.get("/experimenter/ldh").text)
    form = {"name": "wo", "source": str(benchmark_path), "limit": "1", "language": "de", "csrf_token": token}
    created = eve.post("/experimenter/ldh", data=form, follow_redirects=False)
    study_id = int(created.headers["location"].rsplit("/", 1)[1])
    ann = server.services.studies.invite(study_id, "ann")
    client, page = participant(server.url, link(server, study_id, ann))
    assert '<html lang="de"' in page and "Wo ist der Roboter?" in page
    off_map = client.post(link(server, study_id, ann) + "/answers", json={"position": 0, "x": 9.0, "y": 1.0})
    assert off_map.status_code == 409 and off_map.json()["detail"] == "Die Markierung muss auf der Karte liegen."


def test_study_pages_need_the_experimenter(server, benchmark_path):
    study_id = make_study(server.services, benchmark_path)
    anonymous = browser(server.url)
    for path in ("/experimenter/ldh", f"/experimenter/ldh/{study_id}", f"/experimenter/ldh/{study_id}/export.csv"):
        response = anonymous.get(path, follow_redirects=False)
        assert response.status_code == 303 and response.headers["location"] == "/"


def test_answers_survive_a_killed_server(tmp_path, benchmark_path, server_process):
    server = server_process(platform_settings(tmp_path, benchmark=benchmark_path))
    services = server.services
    ensure_experimenter(services)
    study_id = make_study(services, benchmark_path, n=2)
    ann = services.studies.invite(study_id, "ann")
    url = f"/ldh/{StudyTokens(server.settings.signing_key()).issue(study_id, ann)}"
    server.start()
    try:
        client, _ = participant(server.url, url)
        assert client.post(url + "/answers", json={"position": 0, "x": 1.0, "y": 1.0}).status_code == 200
        server.kill()  # SIGKILL right after the acknowledgement: no shutdown to flush anything
        server.start()  # again, on the same port
        page = client.get(url).text
        assert "2 of 2" in page  # the server resumes the participant at the second instance
        assert client.post(url + "/answers", json={"position": 1, "x": 0.6, "y": 0.6}).status_code == 200
    finally:
        server.stop()
    answers = services.studies.answers(study_id)
    assert [(a.position, a.x, a.y) for a in answers] == [(0, 1.0, 1.0), (1, 0.6, 0.6)]


def test_answers_given_at_once_are_all_logged_in_one_order(any_db_settings, benchmark_path):
    """Two participants answering at the same moment, on SQLite and on PostgreSQL: every answer is
    committed once, the study's seqs have no gap and its stamps never go back."""
    from concurrent.futures import ThreadPoolExecutor

    any_db_settings.benchmark = benchmark_path
    services = build_services(any_db_settings)
    ensure_experimenter(services)
    studies = services.studies
    study_id = studies.create(1, "race", str(benchmark_path), "val_seen", "prefix", 4)
    people = [studies.invite(study_id, name) for name in ("ann", "bob", "cy")]

    def answer_all(pid: int) -> None:
        for position in range(4):
            studies.answer(study_id, pid, position, 0.4 + 0.1 * position, 0.5, None)

    with ThreadPoolExecutor(len(people)) as pool:
        list(pool.map(answer_all, people))
    logged = events(services, study_id)
    assert [e.seq for e in logged] == list(range(1, len(logged) + 1))
    assert [e.t_ns for e in logged] == sorted(e.t_ns for e in logged)
    assert sorted((a.participant_id, a.position) for a in studies.answers(study_id)) == sorted(
        (p, k) for p in people for k in range(4)
    )
    services.engine.dispose()


def test_a_study_of_the_platforms_own_trials(tmp_path):
    """From a folder `robotslang export --format ndh` wrote under the data directory: exact instances
    (the dialog up to the Commander's first mark, the tracked pose then); a folder elsewhere is refused."""
    import cv2
    import numpy as np

    from app.export.ndh import write_benchmark
    from app.localization_study import LocalizationStudyError
    from tests.app.trial_log import maze_named, ndh_trial_record

    settings = platform_settings(tmp_path)
    services = build_services(settings)
    ensure_experimenter(services)
    mazes = [maze_named(f"gen-{i:03d}", shift=10 * i) for i in range(3)]
    summary = write_benchmark(
        [(ndh_trial_record(str(i), m.name), m) for i, m in enumerate(mazes)], settings.data_dir / "export"
    )
    split = next(s for s, n in summary.ldh.items() if n)
    studies = services.studies
    study_id = studies.create(1, "ours", str(settings.data_dir / "export"), split, "prefix")
    assert studies.study(study_id).variant == "exact"
    (inst,) = studies.instances(study_id)
    assert (inst.true_x, inst.true_y) == (0.5, 0.53)  # the pose when the Commander first marked the robot
    assert inst.dialog == [
        ["oracle", "hello before the start"],
        ["oracle", "what do you see?"],
        ["navigator", "a red wall"],
    ]
    shown = cv2.imdecode(
        np.frombuffer(studies.map_png(studies.study(study_id).source, inst.run), np.uint8), cv2.IMREAD_COLOR
    )
    assert shown.shape[:2] == mazes[0].labels.shape
    ann = studies.invite(study_id, "ann")
    assert studies.answer(study_id, ann, 0, 0.5, 0.53, None).td == 0.0
    outside = tmp_path / "elsewhere"
    write_benchmark([(ndh_trial_record("9", mazes[0].name), mazes[0])], outside)
    with pytest.raises(LocalizationStudyError, match="configured benchmark or a folder under"):
        studies.create(1, "not ours", str(outside), split, "prefix")
    # A folder named relative to the data directory is the same folder; `..` cannot leave it.
    relative = studies.create(1, "ours again", "export", split, "prefix")
    assert studies.study(relative).source == studies.study(study_id).source
    with pytest.raises(LocalizationStudyError, match="configured benchmark or a folder under"):
        studies.create(1, "not ours", "../elsewhere", split, "prefix")
    services.engine.dispose()

"""MCAP export: read the file back with mcap's own reader, as Foxglove would."""

from __future__ import annotations

import base64
import json

import cv2
import jsonschema
import numpy as np
import pytest
from mcap.reader import make_reader

from app.export.foxglove_scene import CELL_M, wall_cells
from app.export.mcap import CHANNELS, DERIVED_TOPICS, schemas, write_mcap
from app.export.record import ExportError, TrialRecord
from sim.core.labels import Label
from sim.trial.state import LoggedEvent
from tests.app.trial_log import small_maze


def test_every_event_once_in_log_time_order_on_its_channel(record, tmp_path):
    path = write_mcap(record, small_maze(), tmp_path / "trial.mcap")
    with path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert sorted(c.topic for c in summary.channels.values()) == sorted(CHANNELS)
        messages = list(reader.iter_messages(log_time_order=True))
    for schema, _, message in messages:
        jsonschema.validate(json.loads(message.data), schemas()[schema.name])
    log_times = [m.log_time for _, _, m in messages]
    assert log_times == sorted(log_times)
    logged = [(s, c, m) for s, c, m in messages if c.topic not in DERIVED_TOPICS]
    seqs = [m.sequence for _, _, m in logged]
    assert sorted(seqs) == [e.seq for e in sorted(record.events, key=lambda e: e.seq)]
    by_seq = {m.sequence: (c.topic, s.name, json.loads(m.data), m) for s, c, m in logged}
    events = {e.seq: e for e in record.events}
    assert by_seq[7][:2] == ("/chat", "foxglove.Log")
    assert by_seq[7][2]["message"] == "what do you see?" and by_seq[7][2]["name"] == "commander"
    assert by_seq[10][:2] == ("/driver/cmd", "robotslang.DriverCommand")
    assert by_seq[10][2]["outcome"] == "ok" and by_seq[10][2]["stage"] == "executed"
    topic, schema, pose, _ = by_seq[11]
    assert (topic, schema) == ("/robot/pose/sim", "foxglove.PoseInFrame")
    assert pose["pose"]["position"]["y"] == pytest.approx(0.67)
    assert pose["pose"]["orientation"]["z"] == pytest.approx(np.sin(np.pi / 4))
    topic, schema, estimate, _ = by_seq[14]
    assert (topic, schema) == ("/commander/estimate", "foxglove.PoseInFrame")
    assert estimate["pose"]["position"] == {"x": 0.55, "y": 0.6, "z": 0.0}
    assert estimate["pose"]["orientation"] == {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}
    assert by_seq[15][:2] == ("/trial/event", "robotslang.TrialEvent")
    assert by_seq[15][2]["payload"] == {"phase": "navigating", "target_index": 0}
    for seq in (6, 12, 13):
        topic, schema, image, m = by_seq[seq]
        assert schema == "foxglove.CompressedImage" and image["format"] == "jpeg"
        assert topic == ("/overhead/camera" if seq == 13 else "/driver/camera")
        assert m.log_time == events[seq].t_ns
        assert m.publish_time == events[seq].payload["capture_ns"] < m.log_time
        decoded = cv2.imdecode(np.frombuffer(base64.b64decode(image["data"]), np.uint8), cv2.IMREAD_COLOR)
        assert decoded.shape == (48, 64, 3)
        assert abs(int(decoded.mean()) - 40 * events[seq].payload["frame_id"]) <= 2


def test_trial_metadata_and_maze_maps_attached(record, tmp_path):
    maze = small_maze()
    path = write_mcap(record, maze, tmp_path / "trial.mcap")
    with path.open("rb") as f:
        reader = make_reader(f)
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
        attachments = {a.name: a for a in reader.iter_attachments()}
    assert metadata["trial"]["trial_id"] == "7"
    assert metadata["trial"]["team"] == "blue team"
    assert metadata["trial"]["maze"] == "test-maze"
    assert metadata["trial"]["targets"] == "mug,jar,paddle"
    assert set(attachments) == {"maze.map-fixed.png", "maze.map.png"}
    fixed = cv2.imdecode(np.frombuffer(attachments["maze.map-fixed.png"].data, np.uint8), cv2.IMREAD_COLOR)
    assert np.array_equal(fixed, maze.image())
    assert attachments["maze.map.png"].media_type == "image/png"


def test_missing_frame_file_names_the_frame_and_writes_nothing(record, tmp_path):
    (tmp_path / "frames" / "2.jpg").unlink()
    out = tmp_path / "trial.mcap"
    with pytest.raises(ExportError, match=r"trial 7: frame 2 .*frames/2\.jpg"):
        write_mcap(record, small_maze(), out)
    assert not out.exists() and not (tmp_path / "trial.mcap.part").exists()


def read_topic(path, topic: str) -> list[dict]:
    with path.open("rb") as f:
        return [json.loads(m.data) for _, _, m in make_reader(f).iter_messages(topics=[topic])]


def test_robot_frame_follows_each_pose_source(record, tmp_path):
    events = list(record.events)
    events.append(
        LoggedEvent(
            seq=16,
            kind="pose",
            t_ns=events[-1].t_ns + 10_000_000,
            payload={"x": 0.52, "y": 0.69, "heading": 0.0, "source": "tracker"},
        )
    )
    record = TrialRecord(**{**record.__dict__, "events": tuple(events)})
    path = write_mcap(record, small_maze(), tmp_path / "trial.mcap")
    transforms = read_topic(path, "/tf")
    assert [(t["parent_frame_id"], t["child_frame_id"]) for t in transforms] == [
        ("table", "robot/sim"),
        ("table", "robot/sim"),
        ("table", "robot/tracker"),
    ]
    assert transforms[1]["translation"] == {"x": 0.5, "y": 0.67, "z": 0.0}
    assert read_topic(path, "/robot/pose/tracker")[0]["pose"]["position"]["x"] == 0.52


def test_unknown_pose_source_is_refused_before_writing(record, tmp_path):
    events = [
        LoggedEvent(e.seq, e.kind, e.t_ns, {**e.payload, "source": "guess"}) if e.kind == "pose" else e
        for e in record.events
    ]
    record = TrialRecord(**{**record.__dict__, "events": tuple(events)})
    with pytest.raises(ExportError, match=r"pose event 5 has source 'guess'; expected one of sim, tracker"):
        write_mcap(record, small_maze(), tmp_path / "trial.mcap")
    assert not (tmp_path / "trial.mcap").exists()


def test_scene_has_the_walls_and_the_targets_in_visiting_order(record, tmp_path):
    maze = small_maze()
    (scene,) = read_topic(write_mcap(record, maze, tmp_path / "trial.mcap"), "/maze/scene")
    entities = {e["id"]: e for e in scene["entities"]}
    assert set(entities) == {"maze/walls", "target/mug", "target/jar", "target/paddle"}
    for order, target in enumerate(record.targets, start=1):
        (pillar,) = entities[f"target/{target}"]["cylinders"]
        assert (pillar["pose"]["position"]["x"], pillar["pose"]["position"]["y"]) == maze.objects[target]
        assert entities[f"target/{target}"]["texts"][0]["text"] == f"{order}: {target}"
    # The border walls: a full-width run along the bottom (blue) and top (red) rows of cells.
    cubes = entities["maze/walls"]["cubes"]
    cells = wall_cells(maze)
    assert sum(round(c["size"]["x"] / CELL_M) for c in cubes) == int((cells != Label.FLOOR).sum())
    bottom = [c for c in cubes if c["pose"]["position"]["y"] == pytest.approx(CELL_M / 2)]
    assert any(c["size"]["x"] > 2.0 and c["color"]["b"] == 1.0 for c in bottom)
    top_y = (cells.shape[0] - 0.5) * CELL_M
    top = [c for c in cubes if c["pose"]["position"]["y"] == pytest.approx(top_y)]
    assert any(c["size"]["x"] > 2.0 and c["color"]["r"] == 1.0 for c in top)

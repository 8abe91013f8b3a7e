"""Small synthetic mazes whose graphs and observations are known by hand, and the move rules
written plainly (`reference_step`), what the simulator's stepper is held against; the overhead
camera's pinhole projection written plainly (`project`), what its homographies are held against."""

from __future__ import annotations

import json
import re

import numpy as np

from sim.core.dynamics import Action, Pose
from sim.core.geometry import HEADINGS, MAP_HEIGHT_PX, MAP_WIDTH_PX, world_to_pixel
from sim.core.labels import Label
from sim.core.maze import Maze
from sim.core.navgraph import NavGraph
from sim.robot.overhead import OverheadCamera


def reference_step(graph: NavGraph, pose: Pose, action: Action) -> tuple[Pose, bool]:
    """One action, as the rules say it: a forward goes to the graph's next node along the heading,
    or, where there is none, is a collision that leaves the pose; left turns 45 degrees
    counter-clockwise, right clockwise; stop changes nothing. Returns the pose and the collision."""
    if action == Action.FORWARD:
        target = int(graph.forward[pose.node, pose.heading])
        if target < 0:
            return pose, True
        return Pose(target, pose.heading), False
    if action == Action.LEFT:
        return Pose(pose.node, (pose.heading + 1) % HEADINGS), False
    if action == Action.RIGHT:
        return Pose(pose.node, (pose.heading - 1) % HEADINGS), False
    return pose, False


def project(camera: OverheadCamera, points: np.ndarray) -> np.ndarray:
    """(N, 3) table points -> (N, 2) pixels of `camera`."""
    cam = (np.asarray(points, dtype=np.float64).reshape(-1, 3) - np.asarray(camera.position)) @ camera.rotation.T
    uvw = cam @ camera.camera_matrix.T
    return uvw[:, :2] / uvw[:, 2:]


def open_table(objects=((0.5, 0.5), (1.2, 1.0), (2.0, 1.5))) -> np.ndarray:
    """An empty table with a red border and three 16-pixel object blobs at the given (x, y)."""
    labels = np.zeros((MAP_HEIGHT_PX, MAP_WIDTH_PX), dtype=np.uint8)
    labels[:8, :] = labels[-8:, :] = Label.RED
    labels[:, :8] = labels[:, -8:] = Label.RED
    for label, (x, y) in zip((Label.JAR, Label.MUG, Label.PADDLE), objects):
        c, r = (int(v) for v in world_to_pixel(x, y))
        labels[r - 8 : r + 8, c - 8 : c + 8] = label
    return labels


def wall_at_x(labels: np.ndarray, x: float, label: Label = Label.BLUE, y_range=(0.0, 2.06)) -> np.ndarray:
    """Add a vertical wall 10 pixels thick at table x, between the given y values."""
    c, _ = world_to_pixel(x, 0)
    _, r0 = world_to_pixel(0, y_range[1])
    _, r1 = world_to_pixel(0, y_range[0])
    labels[int(max(r0, 0)) : int(min(r1, MAP_HEIGHT_PX)), int(c) - 5 : int(c) + 5] = label
    return labels


def said(result) -> str:
    """The CLI's output with rich's error box and line wrapping taken out."""
    return " ".join(re.sub("[│╭╮╰╯─]", " ", result.output).split())


def export_folder(tmp_path, instances):
    """A platform export's layout: one maze, an empty NDH split and the given LDH instances."""
    Maze.from_labels(open_table(), "m1").save(tmp_path / "mazedata" / "m1")
    (tmp_path / "NDH-data").mkdir()
    (tmp_path / "NDH-data" / "val_seen.json").write_text("[]")
    (tmp_path / "LDH-data").mkdir()
    (tmp_path / "LDH-data" / "val_seen.json").write_text(json.dumps(instances))
    return tmp_path


def exported(idx, pose):
    return {
        "inst_idx": idx,
        "scan": "mazedata/m1/maze/maze.labelled.npz-jar-[1.4 0.7]-[0.5 0.5]",
        "target": "jar",
        "agent_pose": pose,
        "start_pose": pose,
        "commander_estimate": [1.0, 1.0, None],
        "dialog_history": [{"role": "navigator", "message": "red wall to my left"}],
        "all_targets": [[0.5, 0.5], [1.2, 1.0], [2.0, 1.5]],
        "trial_id": "t",
    }

"""What the simulator shows a Driver at a pose: the RayTable row, as the `Saw` percept carries it."""

from __future__ import annotations

import numpy as np

from sim.dynamics import Pose
from sim.observations import RayTable
from sim.perception import RayObservation


def pose_rays(rays: RayTable, pose: Pose) -> RayObservation:
    n, h = pose.node, pose.heading
    return RayObservation(
        labels=rays.labels[n, h],
        depth=rays.depth[n, h],
        too_close=rays.too_close[n, h],
        valid=np.ones(rays.labels.shape[-1], dtype=bool),
        forward_blocked=bool(rays.forward_blocked[n, h]),
    )

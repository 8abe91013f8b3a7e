"""Perception: one front-camera frame -> the simulator's 13-ray observation, from pixels alone.

For each of the 13 rays the camera's calibration says where, in the distorted image, the floor
along that ray's bearing appears at each distance: a ground point d metres away at bearing a is
projected through the pitched pinhole and the radial distortion. Sampling the frame at those
points (three bearings a pixel apart, median per channel) gives a strip from the rover's feet
to 3.3 m. Each sample is classified by colour (one Gaussian per class, from the lab's
calibration); the first run of non-floor samples is where the wall (or object) meets the
floor, refined to a fraction of a pixel where the colour crosses halfway from floor to wall;
its distance is the ray's depth, the colour just above it the ray's label. Too-close follows
from the depth by the simulator's own rule (`sim.core.observations.too_close`).

A frame too dark or too bright to read gets no rays at all (`problem` says why), and a ray
whose colour matches no class is marked not `valid`: never a confident guess.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import TypedDict

import cv2
import numpy as np
from tqdm import tqdm

from sim.core.geometry import GRID_STEP_M, HEADINGS, TURN_RAD, heading_index
from sim.core.labels import N_LABELS, OBJECT_LABELS, OBJECTS, WALL_LABELS, Label
from sim.core.maze import Maze
from sim.core.navgraph import NavGraph
from sim.core.observations import (
    N_RAYS,
    OBS_FEATURES,
    RAY_OFFSETS,
    WALL_CLEARANCE_M,
    cast_rays,
    too_close,
)
from sim.core.rays import FrameProblem, RayObservation
from sim.robot.camera import (
    COLOUR_CLASSES,
    CameraCalibration,
    ColourClass,
    FrontCamera,
    capture,
    undistort_normalized,
)
from sim.robot.frames import FrameError, decode_jpeg

NEAREST_M, FARTHEST_M = 0.02, 3.3  # the strip; the table's diagonal is 3.2 m
SAMPLE_STEP_PX = 0.25  # spacing of strip samples, in image rows
RUN = 3  # consecutive non-floor samples that make a wall base (0.75 px): noise is not a wall
MAX_MAHALANOBIS2 = 30.0  # farther than this from every class: an unknown colour
MIN_BRIGHTNESS_STD = 0.08  # in colour_features brightness units: about a third brighter or darker
DARK_LEVEL = 25  # mean of the brightest channel below this: too dark to read
SATURATED_FRACTION = 0.25  # more clipped pixels than this: overexposed
JITTER_M, JITTER_RAD = 0.015, np.deg2rad(3)  # how far a rover's drifting moves leave it off a node


class PerceptionError(ValueError):
    """A frame or calibration perception cannot work with; the message says what is wrong."""


def features(obs: RayObservation) -> np.ndarray:
    """(OBS_FEATURES,) float32 in `RayTable.features()`'s layout: one-hot labels (13 x 10), depths,
    too-close flags, forward blocked. A ray not read is all zeros: no label, depth 0, not close."""
    out = np.zeros(OBS_FEATURES, dtype=np.float32)
    rays = np.nonzero(obs.valid)[0]
    out[rays * N_LABELS + obs.labels[rays].astype(np.int64)] = 1.0
    start = N_RAYS * N_LABELS
    out[start + rays] = obs.depth[rays]
    out[start + N_RAYS + rays] = obs.too_close[rays]
    out[-1] = obs.forward_blocked
    return out


# -- colours ----------------------------------------------------------------------------------


def colour_features(bgr: np.ndarray) -> np.ndarray:
    """(..., 3) BGR -> (..., 3): chromaticity (b, g share of the sum) and log brightness, so a
    colour in shadow stays near itself while white and the grey table differ by brightness."""
    bgr = np.asarray(bgr, dtype=np.float32)
    s = bgr.sum(axis=-1, keepdims=True)
    chroma = bgr[..., :2] / (s + 15.0)  # the offset keeps dark pixels' chroma from exploding
    return np.concatenate([chroma, np.log(s + 10.0) / 4.0], axis=-1)


@dataclass(frozen=True)
class _Classifier:
    labels: np.ndarray  # (C,) Label value of each class (FLOOR for the table)
    whiten: np.ndarray  # (3, 3C): feature -> each class's whitened coordinates
    offsets: np.ndarray  # (3C,) each class's whitened mean
    log_dets: np.ndarray  # (C,)

    @classmethod
    def of(cls, calibration: CameraCalibration) -> _Classifier:
        if "floor" not in calibration.colours or len(calibration.colours) < 2:
            raise PerceptionError(
                "the calibration has no colours for the floor and the walls; "
                "run perception.calibrate_colours on labelled frames first"
            )
        names = [n for n in COLOUR_CLASSES if n in calibration.colours]
        covs = np.array([calibration.colours[n].cov for n in names])
        means = np.array([calibration.colours[n].mean for n in names])
        # cov^-1 = L^-T L^-1 with L the Cholesky factor: m2 = |L^-1 (f - mean)|^2.
        inv_l = np.linalg.inv(np.linalg.cholesky(covs))  # (C, 3, 3)
        whiten = np.concatenate(list(inv_l.transpose(0, 2, 1)), axis=1).astype(np.float32)
        offsets = np.einsum("cij,cj->ci", inv_l, means).ravel().astype(np.float32)
        return cls(
            labels=np.array([Label[n.upper()] for n in names], dtype=np.uint8),
            whiten=whiten,
            offsets=offsets,
            log_dets=np.linalg.slogdet(covs)[1],
        )

    def classify(self, bgr: np.ndarray) -> np.ndarray:
        """(..., 3) BGR -> (...) int16: a Label value, or -1 for a colour of no class."""
        shape = bgr.shape[:-1]
        z = colour_features(bgr).reshape(-1, 3) @ self.whiten - self.offsets
        m2 = (z * z).reshape(-1, len(self.labels), 3).sum(axis=2)
        best = np.argmin(m2 + self.log_dets, axis=1)
        known = m2[np.arange(len(best)), best] < MAX_MAHALANOBIS2
        bright = np.asarray(bgr).reshape(-1, 3).max(axis=1)
        known &= (bright >= 8) & (bright <= 253)  # black or clipped: its colour is lost
        return np.where(known, self.labels[best].astype(np.int16), np.int16(-1)).reshape(shape)


# -- where each ray's floor appears in the image -----------------------------------------------


@dataclass(frozen=True, eq=False)
class _Strips:
    map_x: np.ndarray  # (K, 13 * 3) float32 distorted image column of each sample
    map_y: np.ndarray
    inside: np.ndarray  # (K, 13) bool: all three bearings of the sample are in the image
    inv_depth: np.ndarray  # (K, 13) 1 / metres along the floor


_strips: dict[tuple[float, ...], _Strips] = {}


def _ray_strips(c: CameraCalibration) -> _Strips:
    key = (c.width, c.height, c.fx, c.fy, c.cx, c.cy, c.k1, c.k2, c.camera_height_m, c.camera_pitch_rad)
    strips = _strips.get(key)
    if strips is None:
        h, pitch = c.camera_height_m, c.camera_pitch_rad
        # Three bearings a pixel apart per ray, kept inside the principal row's field of view.
        widest, _ = undistort_normalized((c.width - 1 - c.cx) / c.fx, 0.0, c.k1, c.k2)
        limit = float(np.arctan(widest)) - 1e-6
        bearings = np.clip(RAY_OFFSETS[:, None] + np.array([-1.0, 0.0, 1.0]) / c.fx, -limit, limit)
        # Uniform in 1/d, which is (nearly) uniform in image rows: SAMPLE_STEP_PX apart.
        step = SAMPLE_STEP_PX * np.cos(RAY_OFFSETS) / (c.fy * h)  # (13,)
        k = np.arange(int(np.ceil((1 / NEAREST_M - 1 / FARTHEST_M) / step.min())) + 1)
        q = np.maximum(1 / NEAREST_M - k[:, None] * step[None, :], 1 / FARTHEST_M)  # (K, 13)
        d = 1 / q[:, :, None]
        forward, left = d * np.cos(bearings), d * np.sin(bearings)  # (K, 13, 3)
        x_cam = -left
        y_cam = h * np.cos(pitch) - forward * np.sin(pitch)
        z_cam = forward * np.cos(pitch) + h * np.sin(pitch)
        xn, yn = x_cam / z_cam, y_cam / z_cam
        r2 = xn * xn + yn * yn
        scale = 1 + c.k1 * r2 + c.k2 * r2 * r2
        u, v = c.cx + c.fx * xn * scale, c.cy + c.fy * yn * scale
        inside = ((u >= 0) & (u <= c.width - 1) & (v >= 0) & (v <= c.height - 1)).all(axis=2)
        inside &= q > 1 / FARTHEST_M  # samples clamped at the far end repeat it
        # The distortion polynomial folds back far outside the image: keep only the monotone part.
        xu, yu = undistort_normalized((u - c.cx) / c.fx, (v - c.cy) / c.fy, c.k1, c.k2)
        inside &= (np.abs(xu - xn) < 1e-3).all(axis=2) & (np.abs(yu - yn) < 1e-3).all(axis=2)
        keep = np.nonzero(inside.any(axis=1))[0]
        if keep.size == 0:
            raise PerceptionError("with this calibration the camera does not see the floor ahead")
        sl = slice(keep[0], keep[-1] + 1)
        strips = _strips[key] = _Strips(
            map_x=u[sl].reshape(-1, N_RAYS * 3).astype(np.float32),
            map_y=v[sl].reshape(-1, N_RAYS * 3).astype(np.float32),
            inside=inside[sl],
            inv_depth=q[sl],
        )
    return strips


def _check_frame(image: np.ndarray | bytes | bytearray | memoryview, calibration: CameraCalibration) -> np.ndarray:
    if isinstance(image, (bytes, bytearray, memoryview)):
        try:
            image = decode_jpeg(image)
        except FrameError as err:
            raise PerceptionError(str(err)) from None
    if not isinstance(image, np.ndarray):
        raise PerceptionError(f"a frame must be a BGR image array or JPEG bytes, got {type(image).__name__}")
    if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3:
        raise PerceptionError(f"a frame must be an (H, W, 3) uint8 BGR image, got {image.dtype} of shape {image.shape}")
    if image.shape[:2] != (calibration.height, calibration.width):
        raise PerceptionError(
            f"frame is {image.shape[1]}x{image.shape[0]} pixels, the calibration "
            f"is for {calibration.width}x{calibration.height}"
        )
    return image


def _exposure_problem(image: np.ndarray) -> FrameProblem | None:
    small = image[::4, ::4]
    brightest = small.max(axis=2)
    if brightest.mean() < DARK_LEVEL:
        return FrameProblem.DARK
    if (brightest >= 254).mean() > SATURATED_FRACTION:
        return FrameProblem.OVEREXPOSED
    return None


def _strip_colours(image: np.ndarray, strips: _Strips) -> np.ndarray:
    """(K, 13, 3) float32: the median of the three bearings' colours at each strip sample."""
    samples = cv2.remap(image, strips.map_x, strips.map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE).reshape(
        -1, N_RAYS, 3, 3
    )
    a, b, c = (samples[:, :, i].astype(np.float32) for i in range(3))
    return np.maximum(np.minimum(a, b), np.minimum(np.maximum(a, b), c))  # median of three


def perceive(
    image: np.ndarray | bytes | bytearray | memoryview, calibration: CameraCalibration, heading: int | None = None
) -> RayObservation:
    """The 13-ray observation seen in one frame (BGR array or JPEG bytes).

    `heading` is the rover's heading index (0..7) when known: the simulator's too-close rule
    allows a longer step on diagonals. Unknown, the diagonal's (longer, so cautious) rule applies.
    """
    image = _check_frame(image, calibration)
    classifier = _Classifier.of(calibration)
    rule_heading = 1 if heading is None else int(heading) % HEADINGS
    problem = _exposure_problem(image)
    if problem is not None:
        nothing = np.zeros(N_RAYS, dtype=bool)
        return RayObservation(
            np.zeros(N_RAYS, np.uint8), np.zeros(N_RAYS, np.float32), nothing, nothing.copy(), False, problem
        )
    strips = _ray_strips(calibration)
    colours = _strip_colours(image, strips)
    classes = classifier.classify(colours)  # (K, 13)
    labels = np.zeros(N_RAYS, dtype=np.uint8)
    depth = np.full(N_RAYS, FARTHEST_M, dtype=np.float32)
    valid = np.zeros(N_RAYS, dtype=bool)
    for ray in range(N_RAYS):
        labels[ray], depth[ray], valid[ray] = _read_ray(
            classes[:, ray], colours[:, ray], strips.inside[:, ray], strips.inv_depth[:, ray]
        )
    objects = np.isin(labels, OBJECT_LABELS) & valid
    depth[objects] = np.maximum(depth[objects] + calibration.object_depth_offset_m, 0.0)
    close = too_close(depth, rule_heading) & valid
    return RayObservation(labels, depth, close, valid, _forward_blocked(depth, valid, rule_heading), None)


def _read_ray(
    classes: np.ndarray, colours: np.ndarray, inside: np.ndarray, inv_depth: np.ndarray
) -> tuple[int, float, bool]:
    """One strip, near to far: (label, depth, valid)."""
    seen = np.nonzero(inside)[0]
    if seen.size < 2 * RUN:
        return Label.FLOOR, FARTHEST_M, False
    cls, col, q = classes[seen], colours[seen], inv_depth[seen]
    solid = cls > 0  # a known wall or object colour; an unknown one is neither floor nor wall
    # First sample of RUN consecutive solid ones: the base of the nearest wall or object.
    runs = np.convolve(solid, np.ones(RUN, dtype=int), mode="valid") == RUN
    if not runs.any():  # open floor all the way, if its far end reads as floor too
        far = cls[-max(len(cls) // 5, 1) :]
        return Label.FLOOR, float(1 / q[-1]), bool((far == Label.FLOOR).mean() > 0.9)
    k0 = int(np.argmax(runs))
    above = cls[k0 + RUN : k0 + RUN + 12]
    above = above[above > 0]
    if above.size == 0:
        return Label.FLOOR, float(1 / q[k0]), False
    votes = np.bincount(above, minlength=N_LABELS)
    label = int(np.argmax(votes))
    if votes[label] < 0.6 * above.size:  # no clear colour: a guess is worse than nothing
        return label, float(1 / q[k0]), False
    if k0 == 0:  # the base is below the bottom of the image: nearer than this
        return label, float(1 / q[0]), True
    return label, float(1 / _crossing(col, q, k0)), True


def _crossing(col: np.ndarray, q: np.ndarray, k0: int) -> float:
    """Sub-pixel base: where the colour passes halfway from the floor's to the wall's, in 1/d."""
    floor = np.median(col[max(k0 - 16, 0) : max(k0 - 4, 1)], axis=0)
    wall = np.median(col[k0 + 4 : k0 + 16], axis=0) if k0 + 4 < len(col) else col[-1]
    span = wall - floor
    norm = float(span @ span)
    if norm < 25.0:
        return float(q[k0])
    lo, hi = max(k0 - 8, 0), min(k0 + 6, len(col))
    t = (col[lo:hi] - floor) @ span / norm
    up = np.nonzero((t[1:] >= 0.5) & (t[:-1] < 0.5))[0]
    if up.size == 0:
        return float(q[k0])
    j = int(up[np.argmin(np.abs(up + 1 + lo - k0))])  # the crossing nearest the detected base
    frac = (0.5 - t[j]) / (t[j + 1] - t[j])
    return float(q[lo + j] + frac * (q[lo + j + 1] - q[lo + j]))


def _forward_blocked(depth: np.ndarray, valid: np.ndarray, heading: int) -> bool:
    """Whether the next node would be within the wall clearance: a seen wall point inside the
    square (axis-aligned on the table) around where a forward move ends."""
    step = GRID_STEP_M * (np.sqrt(2) if heading % 2 else 1.0)
    angles = heading * TURN_RAD + RAY_OFFSETS[valid]
    px, py = depth[valid] * np.cos(angles), depth[valid] * np.sin(angles)
    nx, ny = step * np.cos(heading * TURN_RAD), step * np.sin(heading * TURN_RAD)
    inside = (np.abs(px - nx) < WALL_CLEARANCE_M) & (np.abs(py - ny) < WALL_CLEARANCE_M)
    return bool(inside.any() or (too_close(depth[valid], heading) & (np.abs(RAY_OFFSETS[valid]) < 0.2)).any())


# -- colour calibration -----------------------------------------------------------------------


def calibrate_colours(
    images: Sequence[np.ndarray | bytes],
    truths: Sequence[tuple[np.ndarray, np.ndarray]],
    calibration: CameraCalibration,
    min_samples: int = 50,
) -> CameraCalibration:
    """The calibration with colour classes learned from labelled frames.

    `truths` holds, per image, the (labels, depth) of its 13 rays, as `sim.core.observations.cast_rays`
    gives them at the pose the frame was taken from (in a lab: the rover placed at known poses on
    a known maze). Floor colours come from strip samples well before each ray's depth, label
    colours from just past it; each class is a Gaussian, refitted without its outliers.
    """
    strips = _ray_strips(calibration)
    floor_samples: list[np.ndarray] = []
    label_samples: dict[Label, list[np.ndarray]] = {label: [] for label in Label if label != Label.FLOOR}
    for image, (labels, depth) in zip(images, truths):
        colours = _strip_colours(_check_frame(image, calibration), strips)
        for ray in range(N_RAYS):
            inside, q = strips.inside[:, ray], strips.inv_depth[:, ray]
            d = max(float(depth[ray]), NEAREST_M)
            row_step = q[0] - q[1]  # 1/d per sample
            q_base = 1 / d
            before = inside & (q > q_base + 8 * row_step)
            floor_samples.append(colours[before, ray])
            label = Label(int(labels[ray]))
            if label == Label.FLOOR:
                continue
            past = inside & (q < q_base - 6 * row_step) & (q > q_base - 20 * row_step)
            label_samples[label].append(colours[past, ray])
    # Floor and walls first; an object ray that grazes a footprint's rim can see past it, so
    # object samples are cleaned of anything the floor or a wall already explains.
    fitted: dict[Label, ColourClass | None] = {}
    for label, chunks in [(Label.FLOOR, floor_samples)] + list(label_samples.items()):
        samples = colour_features(np.concatenate(chunks)) if chunks else np.zeros((0, 3), np.float32)
        if label in OBJECT_LABELS:  # the objects are strongly coloured: drop the greys
            neutral = [fitted.get(k) for k in (Label.FLOOR, Label.WHITE)]
            for grey in (c for c in neutral if c is not None):
                samples = samples[_mahalanobis2(samples, grey, dims=2) > 16.0]
        enough = len(samples) >= min_samples
        # A wall in shadow (its end face, a far corner) is darker than any sampled face of it:
        # widen every class but the floor in brightness, where chroma still tells them apart.
        fitted[label] = _fit_gaussian(samples, 0.0 if label == Label.FLOOR else MIN_BRIGHTNESS_STD) if enough else None
    classes = {label.word: c for label, c in fitted.items() if c is not None}
    if "floor" not in classes or len(classes) < 2:
        raise PerceptionError(
            f"too few labelled samples to calibrate colours (classes with at least {min_samples}: {sorted(classes)})"
        )
    calibrated = calibration.with_colours(classes)
    # Objects: the typical gap between where they are seen to stand and their map footprint,
    # where the base is in view (nearer, perception can only say "nearer than the image's bottom").
    nearest_seen = np.array([1 / strips.inv_depth[strips.inside[:, ray], ray][0] for ray in range(N_RAYS)])
    gaps: list[float] = []
    for image, (labels, depth) in zip(images, truths):
        obs = perceive(image, calibrated)
        hit = obs.valid & np.isin(labels, OBJECT_LABELS) & (obs.labels == labels) & (depth > nearest_seen + 0.01)
        gaps.extend(np.asarray(depth)[hit] - obs.depth[hit])
    offset = float(np.clip(np.median(gaps), -0.5, 0.5)) if len(gaps) >= 5 else 0.0
    return calibration.with_colours(classes, offset)


def _mahalanobis2(f: np.ndarray, c: ColourClass, dims: int = 3) -> np.ndarray:
    """Squared Mahalanobis distance to the class, over its first `dims` features (2: chroma)."""
    d = f[:, :dims] - np.asarray(c.mean)[:dims]
    distance: np.ndarray = np.einsum("ni,ij,nj->n", d, np.linalg.inv(np.asarray(c.cov)[:dims, :dims]), d)
    return distance


def _fit_gaussian(f: np.ndarray, min_brightness_std: float = 0.0, rounds: int = 4) -> ColourClass:
    """A Gaussian around the samples' main mode: started from the median and spread of the
    middle half, then refitted to the samples within 3 sigma."""
    mean = np.median(f, axis=0)
    spread = 1.4826 * np.median(np.abs(f - mean), axis=0) + 1e-3
    cov = np.diag(spread**2)
    for _ in range(rounds):
        c = ColourClass(tuple(mean), tuple(map(tuple, cov)))
        keep = f[_mahalanobis2(f, c) < 9.0]
        if len(keep) < 4:
            break
        mean = keep.mean(axis=0)
        cov = np.cov(keep.T) + np.eye(3) * 1e-5  # a floor on the spread: noise-free renders
    cov[2, 2] = max(cov[2, 2], min_brightness_std**2)
    return ColourClass(tuple(float(v) for v in mean), tuple(tuple(float(v) for v in r) for r in cov))


# -- measured against the simulator ------------------------------------------------------------


def random_poses(maze: Maze, graph: NavGraph, n: int, rng: np.random.Generator) -> np.ndarray:
    """(n, 3) continuous poses (x, y, theta) near the graph's nodes and headings, as a rover's
    drifting moves leave it."""
    nodes = graph.nodes[rng.integers(0, graph.n, n)]
    headings = rng.integers(0, HEADINGS, n) * TURN_RAD
    return np.column_stack(
        [nodes + rng.uniform(-JITTER_M, JITTER_M, (n, 2)), headings + rng.uniform(-JITTER_RAD, JITTER_RAD, n)]
    )


def simulated_calibration(
    camera: FrontCamera,
    mazes: Iterable[tuple[Maze, NavGraph]],
    n_frames: int = 60,
    seed: int = 1,
    progress: bool = False,
) -> CameraCalibration:
    """A lab's calibration as the virtual rover would make it: the camera's exact geometry,
    colours learned from `n_frames` frames on `mazes`, at random poses and (one in four)
    looking at each object in turn."""
    rng = np.random.default_rng(seed)
    worlds = list(mazes)
    images: list[np.ndarray | bytes] = []
    truths: list[tuple[np.ndarray, np.ndarray]] = []
    for i in tqdm(range(n_frames), "calibrating colours", disable=not progress):
        if i % 4:
            maze, graph = worlds[i % len(worlds)]
            x, y, theta = random_poses(maze, graph, 1, rng)[0]
        else:  # every fourth frame looks at an object: the three in turn, on each maze in turn
            j = i // 4
            maze, graph = worlds[j // len(OBJECTS) % len(worlds)]
            x, y, theta = _facing(maze, graph, OBJECTS[j % len(OBJECTS)], rng)
        images.append(capture(maze, x, y, theta, camera, rng))
        truths.append(cast_rays(maze, x, y, theta))
    return calibrate_colours(images, truths, camera.calibration())


def _facing(maze: Maze, graph: NavGraph, name: str, rng: np.random.Generator, tries: int = 50) -> np.ndarray:
    """A pose near a node 15 to 60 cm from object `name`, the camera looking at it: a lab
    photographs each object for its colours, which random poses frame too rarely."""
    ox, oy = maze.objects[name]
    away = np.hypot(graph.nodes[:, 0] - ox, graph.nodes[:, 1] - oy)
    near = np.nonzero((away > 0.15) & (away < 0.6))[0]
    for _ in range(tries if near.size else 0):
        x, y = graph.nodes[rng.choice(near)] + rng.uniform(-JITTER_M, JITTER_M, 2)
        theta = float(np.arctan2(oy - y, ox - x) + rng.uniform(-0.3, 0.3))
        if cast_rays(maze, x, y, theta)[0][N_RAYS // 2] == Label[name.upper()]:
            return np.array([x, y, theta])
    anywhere: np.ndarray = random_poses(maze, graph, 1, rng)[0]  # no node sees it from near
    return anywhere


def evaluation_rig(
    mazes: Maze | Sequence[Maze], seed: int, camera: FrontCamera | None, calibration: CameraCalibration | None
) -> tuple[list[tuple[Maze, NavGraph]], FrontCamera, CameraCalibration]:
    """What an evaluation of the front camera runs on: the mazes with their graphs, the camera
    (default: the simulated one) and its colour calibration, given or calibrated on other poses
    (seed + 1000) than the evaluation's."""
    worlds = [(m, NavGraph.build(m)) for m in ([mazes] if isinstance(mazes, Maze) else mazes)]
    camera = camera or FrontCamera()
    if calibration is None:
        calibration = simulated_calibration(camera, worlds, seed=seed + 1000)
    return worlds, camera, calibration


class PerceptionScores(TypedDict):
    label_accuracy: float
    depth_mae_m: float
    too_close_accuracy: float
    walls_label_accuracy: float
    walls_too_close_accuracy: float
    objects_label_accuracy: float
    objects_too_close_accuracy: float
    rays_read: float
    object_rays: float
    poses: int
    near_wall_rays: int


def evaluate_perception(
    mazes: Maze | Sequence[Maze],
    n_poses: int = 300,
    seed: int = 0,
    camera: FrontCamera | None = None,
    calibration: CameraCalibration | None = None,
    progress: bool = False,
) -> PerceptionScores:
    """Perceived rays against `cast_rays` at the same true poses, over random poses on `mazes`
    (a `Maze` or a list). label_accuracy: over all rays, a ray not read counting as wrong;
    depth_mae_m: over the read rays whose true hit is a wall within 1 m; too_close_accuracy:
    over all rays. Label and too-close accuracy over the rays whose true hit is a wall come as
    `walls_*`, over those that meet an object's footprint as `objects_*`. Colours are
    calibrated on other poses than those measured, unless `calibration` is given."""
    worlds, camera, calibration = evaluation_rig(mazes, seed, camera, calibration)
    rng = np.random.default_rng(seed)
    rights: list[np.ndarray] = []
    close_oks: list[np.ndarray] = []
    walls: list[np.ndarray] = []
    things: list[np.ndarray] = []
    reads: list[np.ndarray] = []
    depth_err: list[float] = []
    for i in tqdm(range(n_poses), "perception", disable=not progress):
        maze, graph = worlds[i % len(worlds)]
        x, y, theta = random_poses(maze, graph, 1, rng)[0]
        heading = heading_index(theta)
        labels, true_depth = cast_rays(maze, x, y, theta)
        obs = perceive(capture(maze, x, y, theta, camera, rng), calibration, heading)
        rights.append((obs.labels == labels) & obs.valid)
        close_oks.append(obs.too_close == too_close(true_depth, heading))
        walls.append(np.isin(labels, WALL_LABELS))
        things.append(np.isin(labels, OBJECT_LABELS))
        reads.append(obs.valid)
        near = walls[-1] & (true_depth <= 1.0) & obs.valid
        depth_err.extend(np.abs(obs.depth[near] - true_depth[near]).tolist())
    right, close_ok, wall, thing, read = (np.concatenate(a) for a in (rights, close_oks, walls, things, reads))
    return {
        "label_accuracy": float(right.mean()),
        "depth_mae_m": float(np.mean(depth_err)) if depth_err else float("nan"),
        "too_close_accuracy": float(close_ok.mean()),
        "walls_label_accuracy": float(right[wall].mean()),
        "walls_too_close_accuracy": float(close_ok[wall].mean()),
        "objects_label_accuracy": float(right[thing].mean()) if thing.any() else float("nan"),
        "objects_too_close_accuracy": float(close_ok[thing].mean()) if thing.any() else float("nan"),
        "rays_read": float(read.mean()),
        "object_rays": float(thing.mean()),
        "poses": n_poses,
        "near_wall_rays": len(depth_err),
    }

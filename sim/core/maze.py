"""`Maze`: the label grid of one tabletop maze, from a benchmark PNG or the generator.

Nothing else constructs mazes. A maze keeps two grids, as the benchmark does:
`labels` (walls and the three objects, `maze.map-fixed.png`), used for observations and
renders, and `walls` (walls only, `maze.map.png`), on which the navigation graph is built
so that objects are walkable.
"""

from __future__ import annotations

import hashlib
import struct
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import cv2
import numpy as np
from zlib_ng import zlib_ng

from sim.core.cache import ARRAYS_SUFFIX, load_arrays, save_arrays
from sim.core.cache import cache_dir as default_cache_dir
from sim.core.geometry import MAP_HEIGHT_PX, MAP_WIDTH_PX, pixel_to_world
from sim.core.labels import LABEL_BGR, OBJECT_LABELS, OBJECTS, PALETTE_BGR, Label

LABELS_CACHE_VERSION = 1
FIXED_MAP = "maze.map-fixed.png"
WALLS_MAP = "maze.map.png"


class MazeError(ValueError):
    """A map that cannot be a maze; the message names the file and the problem."""


@dataclass(frozen=True, eq=False)
class Maze:
    name: str
    labels: np.ndarray  # (H, W) uint8 Label values, walls and objects
    walls: np.ndarray  # (H, W) uint8 Label values, walls only
    objects: dict[str, tuple[float, float]] = field(default_factory=dict)  # centroid, metres

    @cached_property
    def content_hash(self) -> str:
        """Hash of both grids: the key of everything cached per maze (computed once: ~5 ms)."""
        h = hashlib.sha256()
        h.update(np.ascontiguousarray(self.walls).tobytes())
        h.update(np.ascontiguousarray(self.labels).tobytes())
        return h.hexdigest()[:16]

    # -- construction -------------------------------------------------------------
    @classmethod
    def from_labels(
        cls, labels: np.ndarray, name: str, walls: np.ndarray | None = None, source: str | None = None
    ) -> Maze:
        """A maze from label grids; `walls` defaults to `labels` with the objects removed."""
        where = source or name
        labels = np.asarray(labels, dtype=np.uint8)
        if labels.shape != (MAP_HEIGHT_PX, MAP_WIDTH_PX):
            raise MazeError(
                f"{where}: map is {labels.shape[1]}x{labels.shape[0]} pixels, expected {MAP_WIDTH_PX}x{MAP_HEIGHT_PX}"
            )
        if walls is None:
            walls = np.where(np.isin(labels, OBJECT_LABELS), Label.FLOOR, labels).astype(np.uint8)
        elif walls.shape != labels.shape:
            raise MazeError(f"{where}: walls map and object map differ in size")
        if np.isin(walls, OBJECT_LABELS).any():
            raise MazeError(f"{where}: the walls-only map contains object colours")
        objects = {}
        for label in OBJECT_LABELS:
            rows, cols = pixels_of(labels, label)
            if rows.size == 0:
                raise MazeError(f"{where}: object {label.word!r} is missing from the map")
            x, y = pixel_to_world(cols.mean(), rows.mean())
            objects[label.word] = (float(x), float(y))
        return cls(name=name, labels=labels, walls=np.asarray(walls, dtype=np.uint8), objects=objects)

    @classmethod
    def from_png(
        cls,
        fixed_path: str | Path,
        walls_path: str | Path | None = None,
        name: str | None = None,
        cache_dir: str | Path | None = None,
        use_cache: bool = True,
    ) -> Maze:
        """Read a benchmark-style map: `maze.map-fixed.png` (+ optional `maze.map.png`).

        The decoded grids are cached beside the graphs, keyed on the PNG files' bytes: hashing
        them is ~20 times cheaper than decoding (about 50 ms a map)."""
        fixed_path = Path(fixed_path)
        name = name or fixed_path.parent.parent.name
        key = maps_key(fixed_path, walls_path)
        path = default_cache_dir(cache_dir) / "labels" / f"{key}-v{LABELS_CACHE_VERSION}{ARRAYS_SUFFIX}"
        if use_cache and path.exists():
            try:
                data = load_arrays(path)
                maze = cls(
                    name=name,
                    labels=data["labels"],
                    walls=data["walls"],
                    objects={w: (float(x), float(y)) for w, (x, y) in zip(OBJECTS, data["objects"])},
                )
                maze.__dict__["content_hash"] = str(data["content_hash"])  # the cached property
                return maze
            except (OSError, ValueError, KeyError):
                pass  # torn or stale: decoded again below
        labels = read_label_png(fixed_path)
        walls = read_label_png(Path(walls_path)) if walls_path is not None else None
        if walls is not None and walls.shape != labels.shape:
            raise MazeError(f"{walls_path}: size differs from {fixed_path}")
        maze = cls.from_labels(labels, name, walls, source=str(fixed_path))
        if use_cache:
            save_arrays(
                path,
                compressed=True,
                labels=maze.labels,
                walls=maze.walls,
                content_hash=maze.content_hash,
                objects=np.array([maze.objects[w] for w in OBJECTS]),
            )
        return maze

    @classmethod
    def from_dir(cls, run_dir: str | Path, name: str | None = None, cache_dir: str | Path | None = None) -> Maze:
        """A maze in the benchmark's layout: `RUN_DIR/maze/maze.map-fixed.png` and `maze.map.png`."""
        fixed, walls = map_files(run_dir)
        if not fixed.exists():
            raise MazeError(f"{fixed}: no such map file")
        return cls.from_png(fixed, walls, name=name or Path(run_dir).name, cache_dir=cache_dir)

    # -- output -------------------------------------------------------------------
    def image(self, walls_only: bool = False) -> np.ndarray:
        """The map as a BGR image in the benchmark's colours."""
        image: np.ndarray = PALETTE_BGR[self.walls if walls_only else self.labels]
        return image

    def save(self, run_dir: str | Path) -> Path:
        """Write the maze in the benchmark's layout; returns the `maze/` folder."""
        folder = Path(run_dir) / "maze"
        folder.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(folder / FIXED_MAP), self.image())
        cv2.imwrite(str(folder / WALLS_MAP), self.image(walls_only=True))
        return folder


def map_files(run_dir: str | Path) -> tuple[Path, Path | None]:
    """A maze folder's maps in the benchmark's layout: `maze.map-fixed.png`, and `maze.map.png` where there is one."""
    folder = Path(run_dir) / "maze"
    walls = folder / WALLS_MAP
    return folder / FIXED_MAP, walls if walls.exists() else None


def maps_key(fixed_path: Path, walls_path: str | Path | None = None) -> str:
    """The key of a maze's map files by their bytes: what its decoded grids are cached under."""
    pngs = [fixed_path.read_bytes() if fixed_path.exists() else b""]
    if walls_path is not None:
        pngs.append(Path(walls_path).read_bytes())
    return hashlib.sha256(b"\0".join(pngs) + bytes([len(pngs)])).hexdigest()[:16]


def pixels_of(grid: np.ndarray, label: Label) -> tuple[np.ndarray, np.ndarray]:
    """The rows and columns of `grid`'s pixels of `label`, in the order `np.nonzero` gives them:
    OpenCV finds a landmark's few thousand pixels in a map four times faster."""
    points = cv2.findNonZero((grid == label).view(np.uint8))
    if points is None:
        return np.empty(0, np.int32), np.empty(0, np.int32)
    cols_rows = points.reshape(-1, 2)
    return cols_rows[:, 1], cols_rows[:, 0]


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _decode_plain_png(data: bytes) -> np.ndarray | None:
    """The RGB pixels of a PNG of the kind the benchmark's maps are (8-bit RGB, not interlaced,
    each row filtered None or Sub), inflated by zlib-ng; None for any other kind (OpenCV reads it).
    OpenCV's libpng spends 13 ms a map inflating with zlib, a fifth of preparing a maze on a fresh
    install; zlib-ng inflates the same in 1 ms, and Sub's running sums are a cumsum."""
    if not data.startswith(_PNG_SIGNATURE):
        return None
    pos, idat, header = len(_PNG_SIGNATURE), [], None
    while pos + 8 <= len(data):
        length, kind = struct.unpack_from(">I4s", data, pos)
        chunk = data[pos + 8 : pos + 8 + length]
        if kind == b"IHDR" and length == 13:
            header = struct.unpack(">IIBBBBB", chunk)
        elif kind == b"IDAT":
            idat.append(chunk)
        elif kind == b"IEND":
            break
        pos += 12 + length
    if header is None:
        return None
    width, height, depth, colour, _, _, interlace = header
    if (depth, colour, interlace) != (8, 2, 0):
        return None
    try:
        raw = zlib_ng.decompress(b"".join(idat))
    except zlib_ng.error:  # type: ignore[misc]  # its stub declares the class an instance
        return None
    if len(raw) != height * (3 * width + 1):
        return None
    rows = np.frombuffer(raw, np.uint8).reshape(height, 3 * width + 1)
    if rows[:, 0].max() > 1:  # Up, Average or Paeth rows: OpenCV
        return None
    rgb = rows[:, 1:].reshape(height, width, 3)
    sub = rows[:, 0] == 1  # each byte the sum of itself and the pixel to its left, mod 256
    if sub.all():
        return np.cumsum(rgb, axis=1, dtype=np.uint8)
    rgb = rgb.copy()
    rgb[sub] = np.cumsum(rgb[sub], axis=1, dtype=np.uint8)
    return rgb


def read_label_png(path: Path) -> np.ndarray:
    """A benchmark PNG to a label grid; unknown colours are an error naming a pixel."""
    try:
        rgb = _decode_plain_png(path.read_bytes())
    except OSError:
        rgb = None
    image = cv2.imread(str(path), cv2.IMREAD_COLOR) if rgb is None else rgb
    if image is None:
        raise MazeError(f"{path}: not a readable image")
    if image.shape[:2] != (MAP_HEIGHT_PX, MAP_WIDTH_PX):
        raise MazeError(
            f"{path}: map is {image.shape[1]}x{image.shape[0]} pixels, expected {MAP_WIDTH_PX}x{MAP_HEIGHT_PX}"
        )
    # The top two bits of each channel tell the palette's colours apart: a 6-bit key, looked up,
    # then every pixel compared with its label's exact colour.
    channels = cv2.split(image)
    b, g, r = (np.asarray(channel, dtype=np.uint8) for channel in (channels if rgb is None else channels[::-1]))
    labels = cv2.LUT(((b >> 6) << 4) | ((g >> 6) << 2) | (r >> 6), _KEY_LABEL)
    wrong = sum(
        cv2.countNonZero(cv2.absdiff(cv2.LUT(labels, _LABEL_CHANNEL[k]), channel))
        for k, channel in enumerate((b, g, r))
    )
    if wrong:
        # Label 255 (a key of no palette colour) repaints as black, which has key 0: never equal.
        bgr = np.stack((b, g, r), axis=2)
        unknown = np.argwhere((_LABEL_CHANNEL[:, labels].transpose(1, 2, 0) != bgr).any(axis=2))
        row, col = unknown[0]
        b, g, r = bgr[row, col]
        raise MazeError(
            f"{path}: {len(unknown)} pixels of unknown colour, first at column {col}, row {row}: BGR ({b}, {g}, {r})"
        )
    return labels


def _palette_tables() -> tuple[np.ndarray, np.ndarray]:
    key_label = np.full(256, 255, dtype=np.uint8)
    channel = np.zeros((3, 256), dtype=np.uint8)  # label -> B, G, R
    for label, (b, g, r) in LABEL_BGR.items():
        key = ((b >> 6) << 4) | ((g >> 6) << 2) | (r >> 6)
        if key_label[key] != 255:
            raise AssertionError(f"palette colours of {Label(key_label[key]).name} and {label.name} share a key")
        key_label[key] = label
        channel[:, label] = (b, g, r)
    return key_label, channel


_KEY_LABEL, _LABEL_CHANNEL = _palette_tables()

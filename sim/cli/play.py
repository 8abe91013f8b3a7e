"""`robotslang sim play`: drive the replay simulator by hand from a terminal.

Each line read is one or more moves (`w`/`forward`, `a`/`left`, `d`/`right`, `s`/`stop`,
`q`/`quit`; `wwad` is four moves). After every move the first-person and top-down frames are
written as PNGs under `--out`, so an image viewer left open on `latest-first-person.png`
follows the drive. Piped input works too: `printf 'wwa\\nq\\n' | robotslang sim play ...`.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import typer

from sim.core.dynamics import Action, Pose, continuous_pose, snap_pose
from sim.core.geometry import TABLE_HEIGHT_M, TABLE_WIDTH_M
from sim.core.labels import Label
from sim.core.maze import Maze, MazeError
from sim.core.navgraph import MODES, NavGraph
from sim.core.observations import N_RAYS, cast_rays
from sim.robot.render import first_person, top_down
from sim.tasks.library import MazeLibrary, UnknownMazeError

# Each action by its word, its initial and its key (w a d s).
WORDS = {
    **{action.word: action for action in Action},
    **{action.word[0]: action for action in Action},
    **dict(zip("wads", (Action.FORWARD, Action.LEFT, Action.RIGHT, Action.STOP), strict=True)),
}
QUIT = {"q", "quit", "exit"}


def parse_moves(line: str) -> list[Action | None]:
    """A typed line to moves; None means quit. Unknown words are a ValueError naming them."""
    moves: list[Action | None] = []
    for word in line.strip().lower().split():
        if word in QUIT:
            moves.append(None)
        elif word in WORDS:
            moves.append(WORDS[word])
        elif re.fullmatch(r"[wads]+", word):
            moves.extend(WORDS[c] for c in word)
        else:
            raise ValueError(f"unknown move {word!r}: use w/forward, a/left, d/right, s/stop, q/quit")
    return moves


@dataclass
class Drive:
    """One hand-driven run: the pose, its path, and where frames are written."""

    maze: Maze
    graph: NavGraph
    pose: Pose
    out: Path
    steps: int = 0
    collisions: int = 0
    path: list[int] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.out.mkdir(parents=True, exist_ok=True)
        self.path.append(self.pose.node)
        self.write_frames()

    def move(self, action: Action) -> bool:
        """Apply one move and write its frames; returns whether a forward move collided."""
        self.pose, collided = self.graph.moves.step(self.pose, action)
        self.steps += 1
        self.collisions += collided
        if self.path[-1] != self.pose.node:
            self.path.append(self.pose.node)
        self.write_frames()
        return collided

    def write_frames(self) -> None:
        x, y, theta = continuous_pose(self.graph, self.pose)
        frames = {
            "first-person": first_person(self.maze, x, y, theta, size=(640, 480)),
            "top-down": top_down(self.maze, pose=(x, y, theta), path=self.graph.nodes[self.path], rays=True),
        }
        for view, image in frames.items():
            _write_png(self.out / f"step-{self.steps:03d}-{view}.png", image)
            _write_png(self.out / f"latest-{view}.png", image)

    def describe(self) -> str:
        """One status line: pose, what is straight ahead, how far each object is by the graph."""
        x, y, theta = continuous_pose(self.graph, self.pose)
        labels, depth = cast_rays(self.maze, x, y, theta)
        ahead = Label(int(labels[N_RAYS // 2]))
        seen = sorted({Label(int(v)).word for v in labels if v != Label.FLOOR})
        here = self.pose.node
        objects = ", ".join(
            f"{name} {self.graph.dist[here, self.graph.nearest_node(*xy)]:.2f} m"
            for name, xy in self.maze.objects.items()
        )
        blocked = " (forward blocked)" if self.graph.moves.blocked(self.pose) else ""
        return (
            f"step {self.steps}: x={x:.2f} y={y:.2f} heading={np.rad2deg(theta):.0f} deg; "
            f"ahead {ahead.word} at {depth[N_RAYS // 2]:.3f} m{blocked}; "
            f"sees {', '.join(seen) or 'nothing'}; to {objects}"
        )


def _write_png(path: Path, image: np.ndarray) -> None:
    # Write then rename, so a viewer watching `latest-*.png` never reads half a file.
    tmp = path.with_name(f".{path.name}.tmp.png")
    if not cv2.imwrite(str(tmp), image):
        raise OSError(f"{path}: could not write the frame")
    os.replace(tmp, path)


def run(drive: Drive, lines: Iterable[str], echo: Callable[[str], object] = print) -> None:
    """Read moves line by line until quit, stop or end of input."""
    echo(drive.describe())
    for line in lines:
        try:
            moves = parse_moves(line)
        except ValueError as err:
            echo(str(err))
            continue
        for action in moves:
            if action is None:
                return
            collided = drive.move(action)
            echo(("collision: " if collided else "") + drive.describe())
            if action == Action.STOP:
                echo(f"stopped after {drive.steps} moves ({drive.collisions} collisions); frames in {drive.out}")
                return


def load_maze(maze: str, benchmark: Path | None) -> Maze:
    """A run folder (`.../Run_318`), or a maze name in the library: bundled (`gen-000`) or,
    given `benchmark`, one of its runs (`Run_318`)."""
    folder = Path(maze)
    if (folder / "maze").is_dir():
        return Maze.from_dir(folder)
    try:
        return MazeLibrary(benchmark).load(maze)
    except (UnknownMazeError, FileNotFoundError) as err:
        hint = "" if benchmark else " (give --benchmark PATH for the benchmark's runs)"
        raise MazeError(f"{err}{hint}") from None


def parse_start(text: str | None) -> tuple[float, float, float]:
    """'X,Y[,THETA_DEG]' in metres and degrees; default: the middle of the table, facing +x."""
    if text is None:
        return TABLE_WIDTH_M / 2, TABLE_HEIGHT_M / 2, 0.0
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) not in (2, 3):
        raise typer.BadParameter(f"{text!r}: expected X,Y or X,Y,THETA_DEGREES", param_hint="--start")
    x, y = values[:2]
    if not (0 <= x <= TABLE_WIDTH_M and 0 <= y <= TABLE_HEIGHT_M):
        raise typer.BadParameter(
            f"({x}, {y}) is off the {TABLE_WIDTH_M} x {TABLE_HEIGHT_M} m table", param_hint="--start"
        )
    return x, y, np.deg2rad(values[2]) if len(values) == 3 else 0.0


def play(
    maze: str = typer.Option(
        "gen-000",
        "--maze",
        help="A run folder (RUN/maze/*.png) or a maze name: bundled (gen-000) or a benchmark run (Run_318).",
    ),
    benchmark: Path | None = typer.Option(
        None, "--benchmark", envvar="ROBOTSLANG_BENCHMARK", help="A RobotSlangBenchmark clone, to find --maze by name."
    ),
    out: Path = typer.Option(Path("play-frames"), "--out", help="Folder for the PNG frames."),
    start: str | None = typer.Option(None, "--start", help="X,Y[,THETA_DEGREES]; snapped to the graph."),
    edges: str = typer.Option("benchmark", "--edges", help="Graph edge mode: benchmark or exact."),
) -> None:
    """Drive the simulator by hand: w/a/d/s (or forward/left/right/stop), q to quit."""
    if edges not in MODES:
        raise typer.BadParameter(f"{edges!r}: expected one of {', '.join(MODES)}", param_hint="--edges")
    try:
        the_maze = load_maze(maze, benchmark)
    except MazeError as err:
        raise typer.BadParameter(str(err), param_hint="--maze") from None
    graph = NavGraph.build(the_maze, edges)
    drive = Drive(the_maze, graph, snap_pose(graph, *parse_start(start)), out)
    typer.echo(
        f"{the_maze.name}: {graph.n} nodes; frames in {out}/latest-first-person.png and "
        f"latest-top-down.png. Moves: w a d s, q quits."
    )

    def lines() -> Iterator[str]:
        while True:
            try:
                yield input("> ")
            except EOFError:
                return

    run(drive, lines(), echo=typer.echo)

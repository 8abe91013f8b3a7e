"""The LDH localizer's live belief for the experimenter's watch page (never for participants).

After each chat message of the localization phase the dialog so far is read by the learned
localizer (`models/ldh.py`) when `ldh_checkpoint` is set, else by the non-learned `colours`
baseline (`sim/tasks/ldh_eval.py`), and the watchers get `{"type": "ldh_belief", "model", "top":
[[x, y, p], ...]}`: the most probable nodes of the maze's main component, metres, p summing to
at most 1. The model runs off the event loop; a belief that finishes after a newer one is dropped.
"""

from __future__ import annotations

import asyncio
import logging
import threading
from collections.abc import Coroutine, Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from app.trial.messages import ServerMessage
from app.trial.port import Connection
from sim.core.maze import Maze
from sim.core.navgraph import NavGraph
from sim.tasks.ldh_eval import MazeContext, colour_logits
from sim.tasks.ldh_features import maze_views, mentions
from sim.trial import events as ev
from sim.trial.events import LoggedEvent
from sim.trial.state import TrialState
from sim.trial.vocabulary import Phase, Role

if TYPE_CHECKING:
    from models.ldh import TrainedLocalizer


class MazeSource(Protocol):
    def load(self, name: str) -> Maze: ...


logger = logging.getLogger(__name__)

TOP_K = 30  # nodes sent per belief: enough to see where the mass is, small on the wire
DIALOG_ROLES = {Role.COMMANDER: "oracle", Role.DRIVER: "navigator"}  # the benchmark's role names


class BeliefModel:
    """One per server: the localizer and each maze's graph and per-pose views, built once. The
    learned localizer (torch) loads on the first belief asked for, not when the server starts."""

    def __init__(self, checkpoint: Path | None, cache_dir: Path) -> None:
        self.cache_dir = cache_dir
        self._checkpoint = checkpoint
        self._loading = threading.Lock()
        self.learned: TrainedLocalizer | None = None
        self.name = "colours"
        self._contexts: dict[str, MazeContext] = {}

    def _load(self) -> None:
        with self._loading:
            if self._checkpoint is None:
                return
            checkpoint, self._checkpoint = self._checkpoint, None
            from models.ldh import load_localizer  # torch only where a checkpoint is configured

            try:
                self.learned, self.name = load_localizer(checkpoint), "learned"
            except Exception as err:  # the server runs on; the page shows which model it sees
                logger.error("LDH checkpoint %s not usable (%s): showing the colours localizer", checkpoint, err)

    def context(self, maze: Maze) -> MazeContext:
        if maze.name not in self._contexts:
            graph = NavGraph.build(maze, "benchmark", cache_dir=self.cache_dir)
            self._contexts[maze.name] = MazeContext(maze.name, graph, maze_views(maze, graph, self.cache_dir))
        return self._contexts[maze.name]

    def node_belief(self, maze: Maze, dialog: Iterable[tuple[str, str]]) -> tuple[MazeContext, np.ndarray]:
        """(context, P(node)) over the main component, from the (role, message) turns so far."""
        self._load()
        ctx = self.context(maze)
        counts = mentions(dialog)
        logits = (
            self.learned.logits(counts, ctx) if self.learned is not None else colour_logits(counts, ctx.required_views)
        )
        logits = np.where(ctx.main[:, None], logits, -np.inf)
        p = np.exp(logits - logits.max())
        node_p = p.sum(axis=1)
        return ctx, node_p / node_p.sum()

    def top(self, maze: Maze, dialog: Iterable[tuple[str, str]], k: int = TOP_K) -> list[list[float]]:
        ctx, node_p = self.node_belief(maze, dialog)
        best = np.argsort(-node_p, kind="stable")[:k]
        return [
            [round(float(ctx.graph.nodes[i, 0]), 4), round(float(ctx.graph.nodes[i, 1]), 4), round(float(node_p[i]), 5)]
            for i in best
            if node_p[i] > 0
        ]


class DialogTrial(Protocol):
    trial_id: int
    history: list[LoggedEvent]  # the dialog so far

    @property
    def state(self) -> TrialState: ...

    def spawn(self, coro: Coroutine[Any, Any, Any]) -> asyncio.Task[Any]: ...


class LiveBelief:
    """A trial's belief feed to its watchers: `after` per event, `welcome` per watcher."""

    def __init__(self, trial: DialogTrial, watchers: set[Connection], model: BeliefModel, mazes: MazeSource) -> None:
        self.trial, self.watchers, self.model, self.mazes = trial, watchers, model, mazes
        self._sent_upto = 0  # the last chat seq a belief was sent for

    def after(self, logged: LoggedEvent) -> None:
        if logged.is_(ev.Chat) and self.watchers and self.trial.state.phase == Phase.LOCALIZING:
            self.trial.spawn(self._send(None))

    def welcome(self, conn: Connection) -> None:
        if self.trial.state.phase == Phase.LOCALIZING:
            self.trial.spawn(self._send(conn))

    async def _send(self, only: Connection | None) -> None:
        rt = self.trial
        chats = [e for e in rt.history if e.is_(ev.Chat)]
        if not chats:
            return
        dialog = tuple(
            (DIALOG_ROLES[e.payload["role"]], e.payload["text"]) for e in chats if e.payload.get("role") in DIALOG_ROLES
        )
        model = self.model
        try:
            maze = self.mazes.load(rt.state.maze)
            top = await asyncio.to_thread(model.top, maze, dialog)
        except Exception:  # the watch page goes without a belief; the trial is untouched
            logger.exception("trial %s: no LDH belief", rt.trial_id)
            return
        if rt.state.phase != Phase.LOCALIZING:
            return  # localization ended while the model ran
        message: dict[str, Any] = {
            "type": ServerMessage.LDH_BELIEF,
            "model": model.name,
            "upto_seq": chats[-1].seq,
            "top": top,
        }
        if only is not None:
            only.deliver(message)
            return
        if chats[-1].seq <= self._sent_upto:
            return
        self._sent_upto = chats[-1].seq
        for conn in list(self.watchers):
            conn.deliver(message)

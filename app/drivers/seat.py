"""`AgentSeat`: a `DriverPolicy` in the Driver's seat of a live trial.

It joins the trial like a browser Driver and hears the same filtered events (dialog and
frames, never the map); it acts through `DriverTrial` alone, so its moves go through the same
rules and event log as a person's. "stop" becomes a claim, announced in the chat; after a
rejection it keeps driving.
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import logging
from typing import Any

from app.drivers.base import DRIVER_ACTIONS
from app.drivers.registry import create_driver
from app.trial.decide import Refused
from app.trial.port import DriverTrial
from app.trial.vocabulary import MoveAction, Phase, Role

logger = logging.getLogger(__name__)
PERCEPTION_WAIT_S = 5.0  # longer than perceiving a frame takes on a loaded machine


class AgentSeat:
    role = Role.DRIVER

    def __init__(self, trial: DriverTrial, services) -> None:
        self.trial, self.services = trial, services
        self.name = trial.state.driver.split(":", 1)[1]
        self.dialog: list[dict[str, str]] = []
        self.frame: bytes | None = None
        self.frame_id: int | None = None
        self.rejected = 0
        self.task: asyncio.Task | None = None

    # What a browser Driver would receive.
    def deliver(self, message: dict[str, Any]) -> None:
        if message.get("type") == "welcome":
            self.dialog = [
                {"role": e["payload"]["role"], "text": e["payload"]["text"]}
                for e in message["history"]
                if e["kind"] == "chat"
            ]
            if "frame" in message:
                self.frame_id, self.frame = message["frame"]["frame_id"], base64.b64decode(message["frame"]["jpeg"])
            return
        if message.get("type") != "event":
            return
        kind, payload = message["kind"], message["payload"]
        if kind == "chat":
            self.dialog.append({"role": payload["role"], "text": payload["text"]})
        elif kind == "frame" and "jpeg" in message:
            self.frame_id, self.frame = payload["frame_id"], base64.b64decode(message["jpeg"])
        elif kind == "target_rejected":
            self.rejected += 1
        elif kind == "target_confirmed":
            self.rejected = 0

    def start(self) -> None:
        self.task = asyncio.get_running_loop().create_task(self._run())

    async def stop(self) -> None:
        if self.task is not None and self.task is not asyncio.current_task():
            self.task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self.task

    async def _run(self) -> None:
        try:
            await self._drive()
        except asyncio.CancelledError:
            raise
        except Exception as err:  # a broken agent must show in the log, not hang the trial silently
            logger.exception("agent %s failed in trial %s", self.name, self.trial.trial_id)
            if not self.trial.state.over:
                self.trial.report_bad_message(Role.DRIVER, f"agent {self.name!r} failed: {err}")

    async def _drive(self) -> None:
        trial, state = self.trial, self.trial.state
        info = {
            "trial_id": trial.trial_id,
            "maze": state.maze,
            "targets": list(state.targets),
            "backend": state.backend,
        }
        policy = await asyncio.to_thread(create_driver, self.name, info, self.services)
        await asyncio.to_thread(policy.reset, info)
        trial.join(self)
        while not trial.state.over:
            await asyncio.sleep(self.services.settings.agent_move_interval_s)
            s = trial.state
            if not s.running or s.pending_claim is not None or s.current_target is None:
                continue
            pose = trial.true_pose()
            observation = {
                "frame": self.frame,
                "frame_id": self.frame_id,
                "target": s.current_target,
                "target_index": s.target_index,
                "rejected": self.rejected,
                "pose": pose,
            }
            if pose is None:  # a rover: what the camera and the particle filter say instead
                observation.update(await self._perceived())
            action = await asyncio.to_thread(policy.act, list(self.dialog), observation)
            await self._act(action)

    async def _perceived(self) -> dict[str, Any]:
        """The rays perceived at the frame after the last move and the belief after it; nothing
        while the trial's filter is not running or has not seen that frame in time."""
        for _ in range(round(PERCEPTION_WAIT_S / 0.02)):
            belief = self.trial.belief
            if belief is not None and belief.settled:
                observed = belief.latest
                b = observed.belief
                return {
                    "rays": observed.rays,
                    "belief": {"x": b.x, "y": b.y, "heading": b.heading, "spread_m": b.spread_m},
                }
            await asyncio.sleep(0.02)
        return {}

    async def _act(self, action: str) -> None:
        trial, s = self.trial, self.trial.state
        if action not in DRIVER_ACTIONS:
            trial.report_bad_message(Role.DRIVER, f"agent {self.name!r} returned {action!r}")
            return
        if action != "stop":
            await trial.request_move(MoveAction(action))
            return
        if s.phase != Phase.NAVIGATING or s.pending_claim is not None or not s.running:
            return
        try:
            trial.say(Role.DRIVER, f"I think I found the {s.current_target}")
            trial.claim()
        except Refused as err:
            logger.info("agent %s: claim refused: %s", self.name, err)

"""A study's webhook: the address its file sets (`StudyConfig.webhook_url`) receives the study's
events as JSON: a pair made (by the lobby or the experimenter), a study trial over, a withdrawal.
Each is POSTed from a worker thread of its own, in order, never from the event loop nor in a
participant's request: a slow or failing receiver is logged and delays nobody. The payload names
participants by their pseudonymous codes only."""

from __future__ import annotations

import json
import logging
import urllib.request
from concurrent.futures import ThreadPoolExecutor
from datetime import UTC, datetime
from enum import StrEnum
from pathlib import Path

from sqlalchemy import select
from sqlalchemy.orm import Session, sessionmaker

from app.db.models import Participant, Trial
from app.study.config import StudyConfigError, StudyFiles
from app.study.lobby import PRACTICE_REASON
from sim.trial.vocabulary import Phase

logger = logging.getLogger("robotslang.study.webhook")
TIMEOUT_S = 5.0  # a receiver slower than this is logged as failing


class WebhookEvent(StrEnum):
    paired = "paired"
    trial_ended = "trial_ended"
    withdrawal = "withdrawal"


class StudyWebhooks:
    def __init__(self, data_dir: Path, db: sessionmaker[Session]) -> None:
        self.files = StudyFiles.of(data_dir)
        self.db = db
        self._worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix="study-webhook")

    def paired(self, trial_id: int) -> None:
        """A pair made, for its study's receiver (once committed)."""
        self._worker.submit(self._trial_event, WebhookEvent.paired, trial_id, {})

    def trial_over(self, trial_id: int, phase: Phase) -> None:
        """A trial over (`phase`: finished or aborted; the row may not say so yet), for its study's
        receiver (a trial of no study: nothing)."""
        self._worker.submit(self._trial_event, WebhookEvent.trial_ended, trial_id, {"phase": str(phase)})

    def withdrawal(self, study: str, code: str) -> None:
        self._worker.submit(self._deliver, study, WebhookEvent.withdrawal, {"participant": code})

    def close(self) -> None:
        self._worker.shutdown(wait=False, cancel_futures=True)

    def _trial_event(self, event: WebhookEvent, trial_id: int, known: dict[str, object]) -> None:
        try:
            with self.db() as db:
                trial = db.get(Trial, trial_id)
                if trial is None or trial.study is None:
                    return
                seats = {trial.commander_id: "commander", trial.driver_id: "driver"}
                codes = db.execute(select(Participant.id, Participant.name).where(Participant.id.in_(seats))).all()
                payload = {
                    "trial_id": trial.id,
                    "phase": trial.phase,
                    "practice": trial.excluded_reason == PRACTICE_REASON,
                    **{seats[pid]: name for pid, name in codes},
                    **known,
                }
                study = trial.study
        except Exception:
            logger.exception("study webhook: trial %s could not be read", trial_id)
            return
        self._deliver(study, event, payload)

    def _deliver(self, study: str, event: WebhookEvent, payload: dict[str, object]) -> None:
        try:
            config = self.files.load(study)
        except (LookupError, StudyConfigError):
            return  # no study file (or one the experimenter must fix): no receiver to tell
        if config.webhook_url is None:
            return
        body = {"event": event, "study": study, "study_version": config.version, "at": datetime.now(UTC).isoformat()}
        request = urllib.request.Request(
            str(config.webhook_url),
            data=json.dumps({**body, **payload}).encode(),
            headers={"Content-Type": "application/json", "User-Agent": "robotslang-study-webhook"},
            method="POST",
        )
        try:
            with urllib.request.urlopen(request, timeout=TIMEOUT_S) as reply:
                reply.read()
        except Exception as err:  # any failure of the receiver's: logged, the study goes on
            logger.warning("study %s: webhook %s for %s failed: %s", study, config.webhook_url, event, err)

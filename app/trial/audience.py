"""`Audience`: who hears a live trial: its seats' sockets (a person's, a relayed one, an agent's
place) and the experimenters' watch views. Each hears an event as its role may (`views.view`), with
what its message carries besides (a frame's image, a claim's photo, the target's name), and the
status when any field but the clocks changes; all of it once the log has committed what it tells."""

from __future__ import annotations

from app.trial import views
from app.trial.log import EventLog
from app.trial.messages import Message, ServerMessage, StatusMessage
from app.trial.port import Connection
from sim.trial import events as ev
from sim.trial.commands import RequestMove
from sim.trial.events import LoggedEvent
from sim.trial.vocabulary import PARTICIPANTS, Role

Attachments = dict[str, dict[str, object]]  # per role: what its message of an event carries besides the event


class Audience:
    def __init__(self, trial_id: int, log: EventLog, watchers: set[Connection]) -> None:
        self.trial_id, self.log, self.watchers = trial_id, log, watchers
        self.seats: dict[str, Connection] = {}
        self._status: dict[str, object] | None = None  # the last status sent, less the clocks

    def send(self, conn: Connection, message: Message) -> None:
        self.log.after_commit(self.trial_id, conn.deliver, message)

    def hear(self, logged: LoggedEvent, attachments: Attachments) -> None:
        listeners = [*self.seats.items(), *((views.EXPERIMENTER, w) for w in self.watchers)]
        for role, conn in listeners:
            message = views.view(role, logged)
            if message is not None:  # the watch page shows the Driver's camera as the Driver gets it
                hears_as = Role.DRIVER if role == views.EXPERIMENTER and logged.is_(ev.FrameRecorded) else role
                self.send(conn, message | attachments.get(hears_as, {}))

    def status(self, status: StatusMessage) -> None:
        unclocked = {k: v for k, v in status.items() if k not in views.CLOCK_FIELDS}
        if unclocked == self._status:
            return
        self._status = unclocked
        for role, conn in list(self.seats.items()):
            if role in PARTICIPANTS:
                self.send(conn, status)
        for conn in list(self.watchers):
            self.send(conn, status)

    def refused(self, conn: Connection, error: str) -> None:
        """The documented reply to a message refused."""
        conn.deliver({"type": ServerMessage.ERROR, "code": "bad_message", "error": error})

    def move_refused(self, request: RequestMove, reason: str, t_ns: int) -> None:
        """The Driver hears now why its move was refused as it came (the log has it with its run)."""
        if (driver := self.seats.get(Role.DRIVER)) is not None:
            reply = {"type": ServerMessage.MOVE_REFUSED, "move_id": request.move_id, "action": str(request.move)}
            self.send(driver, reply | {"reason": reason, "t_ns": t_ns})

    @property
    def empty(self) -> bool:
        return not self.seats and not self.watchers

"""How uvicorn serves the app: `uvicorn_options(settings)` for `robotslang serve`, the demo and the
tests, `log_config()` for a served process's output, and `settle_collector()` once a server
process has started.

A websocket message over the transport limit (`ws_max_size`) is cut off by the websockets
library before the app sees it, with a bare close 1009. `ReplyingWebSocketProtocol` sends the
documented error reply first (`{"type": "error", "code": "bad_message", "error": ...}`), then the
close, and lets the client finish sending before it closes the connection (closing while data
still arrives resets it, and a reset can destroy the reply before the client reads it). The app
hears the close (code 1009) and records the `bad_message`. Messages under the transport limit but
over `max_message_bytes` are answered by the app itself.
"""

from __future__ import annotations

import copy
import gc
import json
import threading
from typing import Any

from uvicorn.protocols.websockets.websockets_sansio_impl import WebSocketsSansIOProtocol
from websockets.exceptions import PayloadTooBig
from websockets.frames import Frame, Opcode

from app.settings import Settings

MESSAGE_TOO_BIG = 1009
LINGER_S = 2.0  # how long the rest of an oversized message may keep arriving after the reply


class ReplyingWebSocketProtocol(WebSocketsSansIOProtocol):
    def handle_parser_exception(self) -> None:
        if self.close_sent:  # the rest of an oversized message: the parser discards it
            return
        if not isinstance(self.conn.parser_exc, PayloadTooBig):
            super().handle_parser_exception()
            return
        error = f"message is over the limit of {self.config.ws_max_size} bytes"
        self.queue.put_nowait({"type": "websocket.disconnect", "code": MESSAGE_TOO_BIG, "reason": error})
        reply = json.dumps({"type": "error", "code": "bad_message", "error": error})
        self.transport.write(Frame(Opcode.TEXT, reply.encode()).serialize(mask=False))
        self.transport.write(b"".join(self.conn.data_to_send()))  # the close frame
        self.close_sent = True
        self.close_timer = self.loop.call_later(LINGER_S, self.transport.close)


def uvicorn_options(settings: Settings) -> dict[str, Any]:
    """Frames and claims are sent inline: the transport limit stays above the message limit. No
    per-message deflate: the largest messages are JPEGs, which do not compress."""
    from app.rover.links import MAX_FRAME_BYTES  # the rover's camera frames are the largest messages

    return {
        "ws": ReplyingWebSocketProtocol,
        "ws_per_message_deflate": False,
        "ws_max_size": max(65536, 4 * settings.max_message_bytes, 2 * MAX_FRAME_BYTES),
        # uvicorn would believe loopback (or FORWARDED_ALLOW_IPS) by default: only the configured proxies.
        "proxy_headers": bool(settings.trusted_proxies),
        "forwarded_allow_ips": settings.trusted_proxies or [],
    }


def log_config() -> dict[str, Any]:
    """uvicorn's logging, and the platform's own loggers (`app.*`, `robotslang.*`) at INFO to the
    same output: without a handler of their own only their warnings reached it, and a lab never
    saw the mazes' preparation progress the docs promise, nor robots connecting. Applied by
    uvicorn in each worker process; not in a test's in-thread server, whose log the test reads."""
    from uvicorn.config import LOGGING_CONFIG

    config = copy.deepcopy(LOGGING_CONFIG)
    config["formatters"]["platform"] = {"format": "%(asctime)s %(levelname)s %(name)s: %(message)s"}
    config["handlers"]["platform"] = {
        "class": "logging.StreamHandler",
        "formatter": "platform",
        "stream": "ext://sys.stderr",
    }
    for name in ("app", "robotslang"):
        config["loggers"][name] = {"handlers": ["platform"], "level": "INFO"}
    return config


def settle_collector() -> None:
    """Take what the process built to start (modules, the app, its services: some 170,000 objects,
    not the trials it reopens, which end and must be freed) out of the collector's full passes. Those passes stop the event loop for as long as they walk
    every long-lived object: 150-170 ms with 200 live trials on the 2-core machine, every half
    minute, the tail of every latency; without the start's objects they walk a third as many.
    Only in a process the server owns (`robotslang serve`, each of its workers): a test's server
    in a thread must not freeze its host's objects, whose cycles would then never be freed."""
    if threading.current_thread() is not threading.main_thread():
        return
    gc.collect()
    gc.freeze()

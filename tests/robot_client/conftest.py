"""The scripted server (tests/robot_client/scripted_server.py) on a loopback port, per test."""

from __future__ import annotations

import pytest
from websockets.asyncio.server import serve

from tests.robot_client.scripted_server import ScriptedServer


@pytest.fixture
async def scripted_server():
    server = ScriptedServer()
    async with serve(server.handler, "127.0.0.1", 0, compression=None) as ws_server:
        port = ws_server.sockets[0].getsockname()[1]
        server.url = f"ws://127.0.0.1:{port}/ws/robot"
        yield server

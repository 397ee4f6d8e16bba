"""A browser that stops reading: the pipeline and the other clients go on, and it is disconnected.

Runs a real server (the in-process test client has no socket buffers to fill) and a client whose
receive buffer is 4 KiB and which never reads.
"""

from __future__ import annotations

import asyncio
import json
import os
import socket
import time
from pathlib import Path

import pytest
import websockets

from gaitscope.server.bench.launch import start_server
from tests.load import post

#: A real server over real sockets: seconds per test, and timing depends on the machine's load.
pytestmark = pytest.mark.slow


async def _watch(port: int, sid: int, seconds: float) -> list[dict]:
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect(("127.0.0.1", port))
    slow = await websockets.connect(
        f"ws://127.0.0.1:{port}/ws/sessions/{sid}?max_rate_hz=0&batch_ms=0", sock=sock, max_queue=1, max_size=None
    )
    health = []
    async with websockets.connect(f"ws://127.0.0.1:{port}/ws/sessions/{sid}?max_rate_hz=0", max_size=None) as good:
        t0 = time.monotonic()
        while time.monotonic() - t0 < seconds:
            msg = json.loads(await good.recv())
            if msg["type"] == "health":
                health.append(msg)
    slow.transport.abort()
    return health


def test_slow_client_is_dropped_without_slowing_anyone(tmp_path: Path) -> None:
    env = {**os.environ, "GAITSCOPE_SLOW_CLIENT_S": "2"}
    server = start_server(tmp_path, "--no-leg-view", "--no-demo", env=env)
    port = server.port
    try:
        base = f"http://127.0.0.1:{port}/api"
        subject = post(f"{base}/subjects", {"code": "S1", "leg_length_m": 0.9, "mass_kg": 70})
        # 1 kHz so that the socket buffers (up to 4 MiB here) fill in seconds rather than a minute
        source = {
            "kind": "simulated",
            "rate_hz": 1000,
            "protocol": [{"speed_m_s": 1.2, "incline_deg": 0, "strides": 60}],
        }
        sid = post(f"{base}/sessions", {"subject_id": subject["id"], "source": source})["id"]
        time.sleep(2.0)
        health = asyncio.run(_watch(port, sid, 25.0))
    finally:
        server.stop()
    assert [h["clients"] for h in health][:2] == [2, 2]
    assert health[-1]["clients"] == 1  # the slow one was disconnected by the server
    rates = [h["rate_hz"] for h in health[1:]]
    assert min(rates) >= 950  # the pipeline kept its 1 kHz throughout
    assert health[-1]["dropped_client"] == 0  # the reading client lost nothing


async def _stop_reading(port: int, sid: int, seconds: float) -> websockets.ConnectionClosed:
    """A client that stops reading for ``seconds`` (its socket's buffers fill), then reads to the end."""
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect(("127.0.0.1", port))
    url = f"ws://127.0.0.1:{port}/ws/sessions/{sid}?max_rate_hz=0&batch_ms=0"
    client = await websockets.connect(url, sock=sock, max_queue=1, max_size=None)
    client.transport.pause_reading()
    await asyncio.sleep(seconds)
    client.transport.resume_reading()
    with pytest.raises(websockets.ConnectionClosed) as closed:
        while True:
            await asyncio.wait_for(client.recv(), 30.0)
    return closed.value


def test_a_client_that_stopped_reading_is_closed_with_1013_and_the_reason(tmp_path: Path) -> None:
    """Issue #21: its close was held back with the data it did not read, and the connection ended in a keepalive
    timeout's 1011; the close now goes past the buffers (server/ws_close.py), and the client finds it, after
    what it had not read, once it reads again."""
    env = {**os.environ, "GAITSCOPE_SLOW_CLIENT_S": "2"}
    server = start_server(tmp_path, "--no-leg-view", "--no-demo", env=env)
    try:
        base = f"http://127.0.0.1:{server.port}/api"
        subject = post(f"{base}/subjects", {"code": "S2", "leg_length_m": 0.9, "mass_kg": 70})
        source = {"kind": "simulated", "rate_hz": 1000,
                  "protocol": [{"speed_m_s": 1.2, "incline_deg": 0, "strides": 60}]}  # fmt: skip
        sid = post(f"{base}/sessions", {"subject_id": subject["id"], "source": source})["id"]
        closed = asyncio.run(_stop_reading(server.port, sid, 10.0))
    finally:
        server.stop()
    assert closed.rcvd is not None, closed  # the server's close arrived (not the client's own keepalive 1011)
    assert closed.rcvd.code == 1013 and closed.rcvd.reason.startswith("client too slow: "), closed.rcvd

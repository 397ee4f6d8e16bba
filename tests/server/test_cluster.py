"""Scale-out through a real proxy (issue #24): ``gaitscope serve --workers 2`` (two nodes behind nginx) on
PostgreSQL, devices and browsers through nginx, and one node killed while they stream.

What must survive: the other node's sessions stream on without a gap; the killed node's sessions end
``stopped`` with their recordings recovered (every state its browsers saw, but for the last second); its
devices, reconnecting through the proxy, are told that their session stopped and why; the node comes
back under its name and takes new sessions.

Runs only against PostgreSQL (``GAITSCOPE_TEST_POSTGRES``, ``scripts/postgres.sh``) and with nginx
installed (``scripts/test.sh`` installs Debian's).
"""

from __future__ import annotations

import asyncio
import itertools
import json
import os
import signal
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest
import websockets

from gaitscope.server.bench.launch import RunningServer, start_server
from gaitscope.server.bench.load import device_frames
from gaitscope.server.workers import WorkersError, find_nginx
from tests.load import call
from tests.waiting import wait_until

RATE = 100.0

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(
        not os.environ.get("GAITSCOPE_TEST_POSTGRES"),
        reason="GAITSCOPE_TEST_POSTGRES is not set (bash scripts/postgres.sh .venv/bin/python -m pytest ...)",
    ),
]


@pytest.fixture
def cluster(tmp_path: Path, database_url: str) -> Iterator[RunningServer]:
    try:
        find_nginx()
    except WorkersError as e:
        pytest.skip(str(e))
    env = {**os.environ, "GAITSCOPE_DATABASE_URL": database_url, "GAITSCOPE_NODE": "gs"}
    env["GAITSCOPE_NODE_TIMEOUT_S"] = "5"  # the survivor takes over if the restart is slower than that
    env["GAITSCOPE_UPLOAD_CHUNK_KB"] = "64"  # an upload of a few chunks, each through the proxy
    log = (tmp_path / "supervisor.log").open("wb")
    try:
        server = start_server(tmp_path / "data", "--no-demo", "--no-leg-view", "--workers", "2", env=env, output=log,
                              timeout=300)  # fmt: skip
    except RuntimeError as e:
        log.close()
        logs = sorted((tmp_path / "data" / "cluster").glob("*.log"))
        shown = [f"{p.name}: {p.read_text()[-1500:]}" for p in [tmp_path / "supervisor.log", *logs]]
        pytest.fail(f"{e}\n" + "\n".join(shown))
    try:
        yield server
    finally:
        server.stop()
        log.close()


def _node_pid(supervisor: int, name: str) -> int:
    """The pid of the node process called ``name`` that ``supervisor`` started."""
    for environ in Path("/proc").glob("[0-9]*/environ"):
        try:
            stat = (environ.parent / "stat").read_text().rsplit(")", 1)[1].split()
            if int(stat[1]) == supervisor and f"GAITSCOPE_NODE={name}".encode() in environ.read_bytes().split(b"\0"):
                return int(environ.parent.name)
        except OSError:
            continue
    raise AssertionError(f"no node {name} under pid {supervisor}")


@dataclass
class Device:
    """What one device saw: when each torque reply came, and how its connection ended."""

    replies: list[float] = field(default_factory=list)
    closed_at: float | None = None


@dataclass
class Browser:
    states: list[tuple[float, int]] = field(default_factory=list)  # (receive time, seq)
    closed_at: float | None = None


async def _device(ws_base: str, sid: int, token: str, frames: list[dict[str, object]], until: float) -> Device:
    out = Device()
    try:
        async with websockets.connect(f"{ws_base}/ws/devices/{sid}?token={token}", max_queue=None) as ws:

            async def replies() -> None:
                async for text in ws:
                    if json.loads(text).get("type") == "torque":
                        out.replies.append(time.monotonic())

            reader = asyncio.create_task(replies())
            start, k = time.monotonic(), 0
            while time.monotonic() < until:
                await asyncio.sleep(max(0.0, start + k / RATE - time.monotonic()))
                await ws.send(json.dumps({**frames[k % len(frames)], "seq": k, "t": k / RATE}))
                k += 1
            await asyncio.sleep(0.3)
            reader.cancel()
    except websockets.ConnectionClosed:
        out.closed_at = time.monotonic()
    return out


async def _browser(ws_base: str, sid: int, until: float) -> Browser:
    out = Browser()
    try:
        async with websockets.connect(f"{ws_base}/ws/sessions/{sid}?max_rate_hz=0&batch_ms=33", max_size=None) as ws:
            while time.monotonic() < until:
                try:
                    text = await asyncio.wait_for(ws.recv(), timeout=max(0.01, until - time.monotonic()))
                except TimeoutError:
                    break
                msg = json.loads(text)
                if msg["type"] == "states":
                    out.states += [(time.monotonic(), s["seq"]) for s in msg["states"]]
    except websockets.ConnectionClosed:
        out.closed_at = time.monotonic()
    return out


async def _closed_with(ws_base: str, sid: int, token: str) -> tuple[int, str]:
    """Connect a device and wait for the server to close it: the close code and reason."""
    async with websockets.connect(f"{ws_base}/ws/devices/{sid}?token={token}") as ws:
        try:
            await asyncio.wait_for(ws.recv(), timeout=10)
        except websockets.ConnectionClosed as e:
            assert e.rcvd is not None
            return e.rcvd.code, e.rcvd.reason
    raise AssertionError(f"session {sid}'s device was not closed")


def test_a_killed_node_loses_no_recording_and_the_other_streams_on(cluster: RunningServer) -> None:
    base, ws_base = cluster.base, cluster.base.replace("http://", "ws://")
    frames = device_frames(RATE)
    channels = [k for k in frames[0] if k != "type"]
    subject = call(base, "POST", "/api/subjects", {"code": "CL01", "leg_length_m": 0.9, "mass_kg": 70})
    source = {"kind": "device", "rate_hz": RATE, "channels": channels}
    made = [call(base, "POST", "/api/sessions", {"subject_id": subject["id"], "source": source}) for _ in range(4)]
    nodes = {s["id"]: s["node"] for s in made}
    assert sorted(nodes.values()) == ["gs-1", "gs-1", "gs-2", "gs-2"]  # new sessions to the least-loaded node
    tokens = {sid: call(base, "POST", f"/api/sessions/{sid}/device-tokens", {})["token"] for sid in nodes}
    victims = [sid for sid, node in nodes.items() if node == "gs-2"]
    survivors = [sid for sid, node in nodes.items() if node == "gs-1"]
    # every session's REST calls reach its node through the proxy (else: 409 "runs on gs-N")
    for sid in nodes:
        call(base, "PATCH", f"/api/sessions/{sid}/settings", {"torque_gain": 0.9})

    async def stream() -> tuple[dict[int, Device], dict[int, Browser], float]:
        until = time.monotonic() + 10.0
        devices = {sid: asyncio.create_task(_device(ws_base, sid, tokens[sid], frames, until)) for sid in nodes}
        browsers = {sid: asyncio.create_task(_browser(ws_base, sid, until)) for sid in nodes}
        await asyncio.sleep(4.0)
        killed = time.monotonic()
        os.kill(_node_pid(cluster.proc.pid, "gs-2"), signal.SIGKILL)
        return ({s: await t for s, t in devices.items()}, {s: await t for s, t in browsers.items()}, killed)

    devices, browsers, killed = asyncio.run(stream())
    for sid in survivors:  # streamed on: torque replies and states until the end, no gap over half a second
        replies = devices[sid].replies
        assert devices[sid].closed_at is None and replies[-1] > killed + 5.0, (sid, devices[sid].closed_at)
        assert max(b - a for a, b in itertools.pairwise(replies)) < 0.5
        assert browsers[sid].closed_at is None and browsers[sid].states[-1][0] > killed + 5.0
    for sid in victims:  # their node died under them
        assert devices[sid].closed_at is not None and devices[sid].closed_at >= killed
        assert browsers[sid].closed_at is not None

    # the killed node's sessions end stopped (its restart or the other node recovers them), nothing recorded lost
    def stopped() -> bool:
        return all(call(base, "GET", f"/api/sessions/{sid}")["state"] == "stopped" for sid in victims)

    wait_until(stopped, timeout=90, what="the killed node's sessions stopped", interval=0.5)
    for sid in victims:
        trials = call(base, "GET", f"/api/trials?session_id={sid}")
        seen = len([t for t, _ in browsers[sid].states if t <= killed])
        assert [t["status"] for t in trials] == ["recovered"], trials
        assert trials[0]["samples"] >= seen - RATE, (trials[0]["samples"], seen)  # at most the last second lost
        events = [e["text"] for e in call(base, "GET", f"/api/sessions/{sid}/events")]
        assert events[-1].endswith("session stopped"), events
        code, reason = asyncio.run(_closed_with(ws_base, sid, tokens[sid]))
        assert code == 4404 and f"session {sid} is not running" in reason, (code, reason)

    # the supervisor started gs-2 again under its name: both nodes live, and a new session runs and answers
    def both_live() -> bool:
        return sorted(n["name"] for n in call(base, "GET", "/api/cluster/nodes") if n["live"]) == ["gs-1", "gs-2"]

    wait_until(both_live, timeout=120, what="gs-2 back after its restart", interval=0.5)
    again = call(base, "POST", "/api/sessions", {"subject_id": subject["id"], "source": source})
    assert again["state"] == "running" and again["node"] == "gs-2"  # the least loaded: gs-1 still runs 2
    token = call(base, "POST", f"/api/sessions/{again['id']}/device-tokens", {})["token"]
    device = asyncio.run(_device(ws_base, again["id"], token, frames, time.monotonic() + 2.0))
    assert len(device.replies) > RATE and device.closed_at is None
    for sid in [*survivors, again["id"]]:
        call(base, "POST", f"/api/sessions/{sid}/stop", {})
    # an upload's chunks all reach the node that began it (it holds the upload in memory): a recovered
    # recording, downloaded and uploaded again through the proxy, chunk by chunk
    with urllib.request.urlopen(f"{base}/api/trials/{trials[0]['id']}/download", timeout=30) as r:
        data = r.read()
    body = {"filename": "recovered.mcap", "size": len(data), "subject_id": subject["id"]}
    up = call(base, "POST", "/api/uploads", body)
    assert len(data) > 2 * up["chunk_size"]
    for offset in range(0, len(data), up["chunk_size"]):
        chunk = data[offset : offset + up["chunk_size"]]
        request = urllib.request.Request(f"{base}/api/uploads/{up['id']}?offset={offset}", data=chunk, method="PUT")
        urllib.request.urlopen(request, timeout=30).close()
    uploaded = call(base, "POST", f"/api/uploads/{up['id']}/finish", {})
    assert uploaded["status"] == "uploaded" and uploaded["samples"] == trials[0]["samples"], uploaded
    # the dashboard's health check stays on one node (its `instance` changes only when that node restarts)
    assert len({call(base, "GET", "/api/health")["instance"] for _ in range(10)}) == 1
    # the route question is the proxy's own: not reachable from outside
    with pytest.raises(urllib.error.HTTPError) as refused:
        call(base, "GET", "/api/cluster/route")
    refused.value.close()
    assert refused.value.code == 404

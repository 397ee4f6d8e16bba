"""Whatever one device sends, another device's torque keeps coming on time (a real server, real sockets).

Reproduces issue 21 (01eb3ed, a 2-core machine): beside a device that declared 2000 Hz and sent every
channel at that rate, a steady 200 Hz device got 31 replies in 7 s (p95 540 ms); beside one sending 5 MB
frames at 200 Hz, 36; three 6.9 MB frames of 500,000 unknown keys stalled the server 14-20 s each and were
each answered with a 42 MB notice. Now a frame's size is bounded before it is read whole (the websocket's
``ws_max_kb``) and before it is parsed (:data:`~gaitscope.sessions.schema.MAX_FRAME_BYTES`), a device declares at
most :data:`~gaitscope.sessions.schema.MAX_DEVICE_RATE_HZ`, notices are short, and each device's work on the event
loop is budgeted (:class:`~gaitscope.sessions.live.sources.DeviceBudget`).

The misbehaving device runs in a process of its own (its frames are built and sent without holding this
process's interpreter), reconnecting at once whenever the server closes it, as a hostile one would.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import math
import multiprocessing
import os
import socket
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from typing import Any

import pytest
import websockets
from websockets.sync.client import connect

from gaitscope.server.bench.launch import RunningServer, start_server
from gaitscope.sessions import schema
from tests.device_tokens import issue_token
from tests.load import p95, post, steady

#: A real server over real sockets: seconds per test, and timing depends on the machine's load.
pytestmark = pytest.mark.slow

#: Seconds the steady device is timed, alone and beside each misbehaving one.
STEADY_S = 3.0
#: The steady device's rate (Hz), a lab's exoskeleton.
RATE = 200.0
#: Fewest round trips a timing counts (3 s at 200 Hz is 600; a loaded machine paces the steady device late).
MIN_ROUND_TRIPS = 300
#: What each misbehaving device does (see :func:`_misbehave`).
KINDS = ("flood", "big", "keys", "keys_fit", "malformed", "binary")


def _full_frame(k: int, t: float) -> str:
    """A frame of every channel, each with a long number (the largest frame a real device sends)."""
    fields: dict[str, object] = {"type": "frame", "version": 2, "seq": k, "t": t, "sent_ns": time.time_ns()}
    for name, ch in schema.CHANNELS.items():
        fields[name] = (k % 2 == 0) if ch.unit == "bool" else 0.123456789012345 * math.sin(t + len(name))
    return json.dumps(fields)


#: The misbehaving process's frames, made once as it starts (:func:`_lowly`), not on the clock of a run.
_FRAMES: dict[str, str] = {}


def _misbehave(port: int, sid: int, token: str, kind: str, end: float, connected: Any) -> dict[str, object]:
    """Misbehave as ``kind`` until ``end`` (``time.monotonic()``, one clock for every process of the machine),
    reconnecting at once after each close; what came back. ``connected`` (an event) is set once it is connected.

    ``flood``: frames of every channel as fast as the socket takes them (at the largest declared rate);
    ``big``: 5 MB frames (a 1M-element array) at 200 Hz; ``keys``: 6.9 MB frames of 500,000 unknown keys;
    ``keys_fit``: frames of as many unknown keys as fit under the frame size limit; ``malformed``: text
    that is not JSON; ``binary``: binary messages. The last four as fast as the socket takes them.

    A send that the server does not read (it reads this device late: its budget) would block past ``end``:
    at ``end`` a timer shuts the socket, so that this returns on time however busy the machine is.
    """
    full, big, keys, keys_fit = (_FRAMES.get(k, "") for k in ("flood", "big", "keys", "keys_fit"))
    url = f"ws://127.0.0.1:{port}/ws/devices/{sid}?token={token}"
    got: dict[str, object] = {"sent": 0, "torque": 0, "notices": {}, "longest_notice": 0, "closes": {}, "connects": 0}
    notices: dict[str, int] = got["notices"]  # type: ignore[assignment]
    closes: dict[str, int] = got["closes"]  # type: ignore[assignment]
    k = 0
    while time.monotonic() < end:
        try:
            with connect(url, max_queue=None, max_size=None, open_timeout=5, close_timeout=1) as ws:
                got["connects"] = int(got["connects"]) + 1  # type: ignore[call-overload]
                connected.set()
                deadline = threading.Timer(max(0.0, end - time.monotonic()), _shut, (ws.socket,))
                deadline.daemon = True
                deadline.start()
                start = time.monotonic()
                while time.monotonic() < end:
                    if kind == "flood":
                        ws.send(full % (k, k / schema.MAX_DEVICE_RATE_HZ))
                    elif kind == "big":
                        ws.send(big)
                        time.sleep(max(0.0, start + k / 200 - time.monotonic()))
                    elif kind == "keys":
                        ws.send(keys)
                    elif kind == "keys_fit":
                        ws.send(keys_fit)
                    elif kind == "malformed":
                        ws.send('{"type": "frame", "seq": ')
                    else:
                        ws.send(b"\x00\x01" * 64)
                    k += 1
                    got["sent"] = k
                    while True:  # what has come back so far
                        try:
                            text = ws.recv(timeout=0)
                        except TimeoutError:
                            break
                        got["longest_notice"] = max(int(got["longest_notice"]), len(text))  # type: ignore[call-overload]
                        message = json.loads(text)
                        if message["type"] == "torque":
                            got["torque"] = int(got["torque"]) + 1  # type: ignore[call-overload]
                        else:
                            notices[message["kind"]] = notices.get(message["kind"], 0) + 1
                deadline.cancel()
        except websockets.ConnectionClosed as e:
            if time.monotonic() >= end:
                break  # shut by the deadline, not closed by the server
            code = e.rcvd.code if e.rcvd is not None else 1006
            closes[str(code)] = closes.get(str(code), 0) + 1
        except OSError:  # refused, reset (or shut by the deadline: the loop ends)
            if time.monotonic() < end:
                closes["reset"] = closes.get("reset", 0) + 1
    return got


def _shut(sock: socket.socket) -> None:
    with contextlib.suppress(OSError):
        sock.shutdown(socket.SHUT_RDWR)


def _lowly() -> None:
    """The misbehaving process's start: the machine's last claim on a core, no log of the server's closes,
    and its frames made (a 6.9 MB one takes seconds at nice 19 on a busy machine).

    On one machine the attacker's own CPU would otherwise slow the steady device's client and the server
    alike, which is not what is measured here (a real one sits on another machine)."""
    os.nice(19)
    logging.getLogger("websockets").setLevel(logging.CRITICAL)  # its reader's "stream ended" as the server closes
    # a template: the device spends its time sending, not making frames
    _FRAMES["flood"] = _full_frame(0, 0.0).replace('"seq": 0,', '"seq": %d,', 1).replace('"t": 0.0,', '"t": %r,', 1)
    _FRAMES["big"] = json.dumps({"type": "frame", "seq": 0, "t": 0.0, "foot_angle_deg": [0.5] * 1_000_000})
    _FRAMES["keys"] = json.dumps({"type": "frame", "seq": 0, "t": 0.0, **{f"x{i}": 0 for i in range(500_000)}})
    _FRAMES["keys_fit"] = json.dumps({"type": "frame", "seq": 0, "t": 0.0, **{f"x{i}": 0 for i in range(1_500)}})


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningServer]:
    server = start_server(tmp_path_factory.mktemp("isolation"), "--no-leg-view", "--no-demo")
    yield server
    server.stop()


def _device_session(base: str, rate_hz: float) -> int:
    subject = post(f"{base}/api/subjects", {"code": f"D{time.monotonic_ns()}", "leg_length_m": 0.9, "mass_kg": 70})
    body = {"subject_id": subject["id"], "source": {"kind": "device", "rate_hz": rate_hz}}
    return int(post(f"{base}/api/sessions", body)["id"])


def test_a_device_may_not_declare_over_the_largest_rate(server: RunningServer) -> None:
    with pytest.raises(urllib.error.HTTPError) as e:
        _device_session(server.base, 2000.0)
    assert e.value.code == 422 and "1000" in e.value.read().decode()


def test_whatever_a_device_sends_the_other_gets_every_torque_on_time(server: RunningServer) -> None:
    base = server.base
    steady_sid = _device_session(base, RATE)
    settings = json.loads(urllib.request.urlopen(f"{base}/api/sessions/{steady_sid}", timeout=10).read())["settings"]
    bound = settings["max_torque_Nm"]
    alone = asyncio.run(steady(server.port, steady_sid, issue_token(base, steady_sid), STEADY_S, RATE))
    assert len(alone.rtts) == alone.sent >= MIN_ROUND_TRIPS
    quiet = p95(alone.rtts)
    print(f"alone: {alone.sent} sent, {len(alone.rtts)} answered, p95 {quiet * 1e3:.1f} ms")
    results: dict[str, tuple[int, int, float, dict[str, object]]] = {}
    spawn = multiprocessing.get_context("spawn")
    with spawn.Pool(1, initializer=_lowly) as pool, spawn.Manager() as manager:
        pool.apply(time.sleep, (0,))  # started: the misbehaving device's imports are done, its frames made
        for kind in KINDS:
            other = _device_session(base, schema.MAX_DEVICE_RATE_HZ if kind == "flood" else RATE)
            token = issue_token(base, other)
            end = time.monotonic() + 0.7 + STEADY_S + 0.3
            connected = manager.Event()
            bad = pool.apply_async(_misbehave, (server.port, other, token, kind, end, connected))
            assert connected.wait(60), kind  # connected, and sending from then on
            run = asyncio.run(steady(server.port, steady_sid, issue_token(base, steady_sid), STEADY_S, RATE))
            # it stops itself at `end`; the wait only covers a machine too busy to give a nice-19 process a turn
            got = bad.get(timeout=120)
            results[kind] = (run.sent, len(run.rtts), p95(run.rtts) if run.rtts else math.inf, got)
            print(
                f"{kind}: {run.sent} sent, {len(run.rtts)} answered, p95 {results[kind][2] * 1e3:.1f} ms; it got {got}"
            )
            assert all(math.isfinite(x) and abs(x) <= bound for x in run.torques), kind
    again = asyncio.run(steady(server.port, steady_sid, issue_token(base, steady_sid), STEADY_S, RATE))
    print(f"alone again: {again.sent} sent, {len(again.rtts)} answered, p95 {p95(again.rtts) * 1e3:.1f} ms")
    quiet = max(quiet, p95(again.rtts))  # the machine's load drifts: the quieter of the two would be unfair
    report = {k: (s, n, round(p * 1e3, 1), g) for k, (s, n, p, g) in results.items()}
    for kind, (sent, replies, late, got) in results.items():
        assert replies == sent >= MIN_ROUND_TRIPS, (kind, report)  # every frame answered, none 3 s late
        # the issue's quiet p95 + 10 ms, with room for a loaded 2-core machine running both ends
        assert late <= quiet + 0.025, (kind, quiet, report)
        assert int(got["longest_notice"]) < 2000, (kind, report)  # type: ignore[call-overload]
    # and each was refused as it should be: by the websocket's limit before it was read, or by a short notice
    assert all("1009" in results[k][3]["closes"] for k in ("big", "keys")), report  # type: ignore[operator]
    for kind, notice in (("keys_fit", "too_large"), ("malformed", "invalid"), ("binary", "binary")):
        assert notice in results[kind][3]["notices"] and "1008" in results[kind][3]["closes"], report  # type: ignore[operator]
    assert int(results["flood"][3]["torque"]) > 0, report  # type: ignore[call-overload]
    health = json.loads(urllib.request.urlopen(f"{base}/api/sessions/{steady_sid}", timeout=10).read())
    assert health["state"] == "running"

"""A steady device beside a misbehaving load, for the tests on a real server over real sockets (accounts off
unless said): REST calls, the device's frames of a walk, its round trips timed at its rate, their p95; and
a session's time read from its stream.

The steady device paces itself at its declared rate on the real clock (a real device's frames come at its
rate, and the round trip of each is what these tests time): the one sleep here is that pacing.
"""

from __future__ import annotations

import asyncio
import json
import math
import ssl
import time
import urllib.request
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import websockets
from websockets.sync.client import connect

#: The seven version 1 channels of a walk at 1 Hz: each one's value at phase angle ``w`` (rad).
_WALK: dict[str, Callable[[float], float]] = {
    "foot_angle_deg": lambda w: 25 * math.sin(w),
    "foot_vel_dps": lambda w: 150 * math.cos(w),
    "shank_angle_deg": lambda w: 20 * math.sin(w),
    "shank_vel_dps": lambda w: 120 * math.cos(w),
    "heel_forward_m": lambda w: 0.1 * math.sin(w),
    "heel_up_m": lambda w: 0.05 + 0.05 * math.cos(w),
    "thigh_angle_deg": lambda w: 15 * math.sin(w),
}
WALK_CHANNELS = tuple(_WALK)


def post(url: str, body: dict[str, Any], headers: dict[str, str] | None = None) -> Any:
    """POST ``body`` as JSON to ``url``; the JSON answer (an error status raises ``HTTPError``)."""
    all_headers = {"Content-Type": "application/json", **(headers or {})}
    req = urllib.request.Request(url, json.dumps(body).encode(), all_headers, method="POST")
    with urllib.request.urlopen(req, timeout=10) as r:
        return json.loads(r.read())


def call(base: str, method: str, path: str, body: Any = None, context: ssl.SSLContext | None = None) -> Any:
    """One JSON request to ``base + path`` (``body`` as JSON, if any); the JSON answer (an error status raises
    ``HTTPError``). ``context``: the TLS context of an ``https`` base."""
    data = None if body is None else json.dumps(body).encode()
    request = urllib.request.Request(f"{base}{path}", data=data, method=method)
    if data is not None:
        request.add_header("Content-Type", "application/json")
    with urllib.request.urlopen(request, timeout=30, context=context) as r:
        return json.loads(r.read())


def walk_frame(k: int, t: float, channels: tuple[str, ...] = WALK_CHANNELS) -> str:
    """Frame ``k`` at device time ``t`` (s) of a 1 Hz walk: ``channels`` of :data:`WALK_CHANNELS`."""
    w = 2 * math.pi * t
    return json.dumps({"type": "frame", "seq": k, "t": t, **{c: _WALK[c](w) for c in channels}})


@dataclass
class Steady:
    """What a steady device got: frames sent, torque replies, and of the replies to the frame just sent
    (its ``seq``) the round trips (s) and torques (Nm)."""

    sent: int = 0
    replies: int = 0
    rtts: list[float] = field(default_factory=list)
    torques: list[float] = field(default_factory=list)


async def steady(
    port: int,
    sid: int,
    token: str,
    seconds: float,
    rate_hz: float = 200.0,
    frame: Callable[[int, float], str] = walk_frame,
    reply_timeout: float = 3.0,
) -> Steady:
    """A device at ``rate_hz`` on session ``sid`` for ``seconds``, one frame at a time: each sent at its due
    time and its reply awaited (at most ``reply_timeout`` s: a later one ends the run)."""
    out = Steady()
    async with websockets.connect(f"ws://127.0.0.1:{port}/ws/devices/{sid}?token={token}") as ws:
        start = time.monotonic()
        while time.monotonic() - start < seconds:
            await asyncio.sleep(max(0.0, start + out.sent / rate_hz - time.monotonic()))  # the device's rate
            t_send = time.monotonic()
            await ws.send(frame(out.sent, out.sent / rate_hz))
            out.sent += 1
            try:
                reply = json.loads(await asyncio.wait_for(ws.recv(), timeout=reply_timeout))
            except TimeoutError:
                break
            if reply["type"] == "torque":
                out.replies += 1
                if reply["seq"] == out.sent - 1:
                    out.rtts.append(time.monotonic() - t_send)
                    out.torques.append(reply["torque_Nm"])
    return out


def session_time(
    base: str,
    session_id: int,
    at_least: float = -math.inf,
    headers: dict[str, str] | None = None,
    timeout: float = 60.0,
) -> float:
    """The running session's time (s, of its last state) on the real server at ``base``, read from its browser
    stream (``headers``: a login's cookie, with accounts on); with ``at_least``, once it has reached that (the
    stream's states come as the session makes them).

    Raises:
        AssertionError: not reached in ``timeout`` seconds."""
    url = base.replace("http://", "ws://") + f"/ws/sessions/{session_id}?max_rate_hz=20"
    deadline = time.monotonic() + timeout
    with connect(url, additional_headers=headers or {}) as ws:
        while True:
            left = deadline - time.monotonic()
            assert left > 0, f"session {session_id} did not reach t = {at_least:g} s in {timeout:g} s"
            message = json.loads(ws.recv(timeout=left))
            if message.get("type") == "states" and message["states"]:
                t = float(message["states"][-1]["t"])
                if t >= at_least:
                    return t


def p95(xs: list[float]) -> float:
    """The 95th percentile of ``xs`` (the value 95 % of the way through them sorted)."""
    return sorted(xs)[int(0.95 * len(xs))]

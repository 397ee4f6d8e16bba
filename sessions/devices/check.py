"""``gaitscope device-check URL TOKEN``: does this endpoint keep gaitscope's device protocol (``docs/api.md``)?

A conformance run a device team points at gaitscope's server, or at their own implementation of its side of the
protocol (a bench simulator, a proxy), before a person wears the device. Each check says what it sent, what
came back and whether that is what the protocol promises:

- ``handshake``: the token opens the socket; ``bad token``: a wrong one is refused (HTTP 401/403, or close 1008);
- ``torque per frame``: every valid frame gets a ``TorqueCommand`` of its ``seq``, finite, in ``[0, max]``;
- ``invalid``, ``binary``, ``too large``, ``order``: the ``DeviceNotice`` of that kind, and the socket stays open;
- ``reboot``: a clock that restarts is resynchronised: the next frame still gets its torque;
- ``rate``: frames far over the declared rate get a ``rate`` notice (some dropped), not a closed socket;
- ``malformed in a row``: 50 malformed frames in a row close the socket with 1008;
- ``reconnect``: the device may connect again afterwards.

Uses the standard library and ``websockets`` only (what a device's controller has).
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any, Final

from websockets.exceptions import ConnectionClosed, InvalidStatus, WebSocketException
from websockets.sync.client import ClientConnection, connect

__all__ = ["CHECKS", "Check", "run_checks"]

#: How long a reply may take in a check (s): generous, a conformance run is not a latency test.
REPLY_S: Final = 2.0
#: A frame just over the protocol's 16 KiB limit, under the websocket's own 64 KiB.
TOO_LARGE_BYTES: Final = 20_000
MALFORMED_IN_A_ROW: Final = 50


@dataclass(frozen=True)
class Check:
    """One check's outcome."""

    name: str
    passed: bool
    detail: str


class _Device:
    def __init__(self, url: str, token: str, rate_hz: float, max_torque: float):
        self.url, self.token, self.rate_hz, self.max_torque = url, token, rate_hz, max_torque
        self.seq = 0
        self.t = 100.0  # the device's clock (s)

    def connect(self, token: str | None = None) -> ClientConnection:
        headers = {"Authorization": f"Bearer {token if token is not None else self.token}"}
        return connect(self.url, additional_headers=headers, open_timeout=10, close_timeout=2, max_size=2**20)

    def frame(self, **extra: Any) -> str:
        self.seq += 1
        self.t += 1.0 / self.rate_hz
        body = {"type": "frame", "version": 2, "seq": self.seq, "t": self.t, "foot_angle_deg": 10.0 * math.sin(self.t)}
        return json.dumps({**body, **extra})

    def replies(self, ws: ClientConnection, seconds: float = REPLY_S) -> Iterator[dict[str, Any]]:
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0:
            try:
                raw = ws.recv(timeout=left)
            except TimeoutError:
                return
            try:
                msg = json.loads(raw)
            except (TypeError, ValueError):
                yield {"type": "?", "raw": str(raw)[:80]}
                continue
            yield msg if isinstance(msg, dict) else {"type": "?", "raw": str(raw)[:80]}

    def torque_for(self, ws: ClientConnection, seq: int) -> tuple[bool, str]:
        """Whether the reply to frame ``seq`` is a valid torque (skipping replies to earlier frames)."""
        for msg in self.replies(ws):
            if msg.get("type") == "torque" and msg.get("seq") == seq:
                tq = msg.get("torque_Nm")
                if not isinstance(tq, int | float) or not math.isfinite(tq) or not 0 <= tq <= self.max_torque:
                    return False, f"frame {seq}: torque_Nm {tq!r} is not a finite number in [0, {self.max_torque:g}]"
                return True, f"frame {seq}: {tq:.3f} N m"
            if msg.get("type") == "error" and msg.get("seq") == seq:
                return False, f"frame {seq}: a notice instead of a torque: {str(msg)[:160]}"
            if msg.get("type") not in ("torque", "error"):
                return False, f"frame {seq}: a reply that is neither torque nor notice: {str(msg)[:160]}"
        return False, f"frame {seq}: no reply within {REPLY_S:g} s"

    def notice(self, ws: ClientConnection, kind: str, seconds: float = REPLY_S) -> tuple[bool, str]:
        seen = []
        for msg in self.replies(ws, seconds):
            if msg.get("type") == "error" and msg.get("kind") == kind:
                return True, f"notice {kind}: {str(msg.get('detail'))[:100]}"
            seen.append(str(msg.get("kind") or msg.get("type")))
        return False, f"no {kind!r} notice within {seconds:g} s (got: {', '.join(seen[:5]) or 'nothing'})"


def _handshake(d: _Device, ws: ClientConnection) -> tuple[bool, str]:
    return True, f"connected to {d.url}"


def _torques(d: _Device, ws: ClientConnection) -> tuple[bool, str]:
    last = ""
    for _ in range(20):
        ws.send(d.frame())
        ok, last = d.torque_for(ws, d.seq)
        if not ok:
            return False, last
        time.sleep(1.0 / d.rate_hz)
    return True, f"20 of 20 frames answered; last {last}"


def _invalid(d: _Device, ws: ClientConnection) -> tuple[bool, str]:
    ws.send(d.frame(foot_angle_deg="not a number"))
    return _then_alive(d, ws, d.notice(ws, "invalid"))


def _binary(d: _Device, ws: ClientConnection) -> tuple[bool, str]:
    ws.send(b"\x00\x01binary")
    return _then_alive(d, ws, d.notice(ws, "binary"))


def _too_large(d: _Device, ws: ClientConnection) -> tuple[bool, str]:
    ws.send(d.frame(padding="x" * TOO_LARGE_BYTES))
    return _then_alive(d, ws, d.notice(ws, "too_large"))


def _order(d: _Device, ws: ClientConnection) -> tuple[bool, str]:
    ws.send(d.frame())
    d.torque_for(ws, d.seq)
    d.t -= 0.2  # 0.2 s back: a reordered frame, not a reboot
    ws.send(d.frame())
    result = d.notice(ws, "order")
    d.t += 0.3
    return _then_alive(d, ws, result)


def _reboot(d: _Device, ws: ClientConnection) -> tuple[bool, str]:
    d.t = 0.0  # the device's clock restarted
    ws.send(d.frame())
    ok, detail = d.torque_for(ws, d.seq)
    return ok, ("the clock restarted at 0 s and " + detail) if ok else detail


def _rate(d: _Device, ws: ClientConnection) -> tuple[bool, str]:
    n = int(6 * d.rate_hz)  # 6 s of frames at once: beyond the 2 s burst the protocol allows
    for _ in range(n):
        ws.send(d.frame())
    result = d.notice(ws, "rate", seconds=10.0)
    time.sleep(2.5)  # back under the rate before the next check
    for _ in d.replies(ws, 0.5):
        pass
    return _then_alive(d, ws, result)


def _malformed(d: _Device, ws: ClientConnection) -> tuple[bool, str]:
    try:
        for _ in range(MALFORMED_IN_A_ROW + 5):
            ws.send("{not json")
        for _ in d.replies(ws, 10.0):
            pass
    except ConnectionClosed as e:
        code = e.rcvd.code if e.rcvd is not None else None
        reason = e.rcvd.reason if e.rcvd is not None else ""
        return code == 1008, f"closed with {code} ({reason})"
    return False, f"still open after {MALFORMED_IN_A_ROW + 5} malformed frames in a row"


def _then_alive(d: _Device, ws: ClientConnection, result: tuple[bool, str]) -> tuple[bool, str]:
    """The check's result, failed if the socket did not stay open for the next valid frame."""
    ok, detail = result
    ws.send(d.frame())
    alive, after = d.torque_for(ws, d.seq)
    if not alive:
        return False, f"{detail}; then {after}"
    return ok, detail


#: The checks on one connection, in order (each gets the connection the previous left open).
CHECKS: Final[tuple[tuple[str, Callable[[_Device, ClientConnection], tuple[bool, str]]], ...]] = (
    ("handshake", _handshake),
    ("torque per frame", _torques),
    ("invalid", _invalid),
    ("binary", _binary),
    ("too large", _too_large),
    ("order", _order),
    ("reboot", _reboot),
    ("rate", _rate),
    ("malformed in a row", _malformed),
)


def run_checks(url: str, token: str, rate_hz: float = 100.0, max_torque_Nm: float = 80.0) -> list[Check]:
    """Every check against the endpoint at ``url`` (``ws://.../ws/devices/{id}``) with ``token``."""
    d = _Device(url, token, rate_hz, max_torque_Nm)
    out: list[Check] = []
    try:
        d.connect(token + "-wrong").close()
        out.append(Check("bad token", False, "a wrong token opened the socket"))
    except InvalidStatus as e:
        status = e.response.status_code
        out.append(Check("bad token", status in (401, 403), f"refused with HTTP {status}"))
    except (OSError, WebSocketException, TimeoutError) as e:
        out.append(Check("bad token", False, f"{type(e).__name__}: {e}"))
    try:
        ws = d.connect()
    except (OSError, WebSocketException, TimeoutError) as e:
        return [*out, Check("handshake", False, f"{type(e).__name__}: {e}")]
    with ws:
        for name, check in CHECKS:
            try:
                ok, detail = check(d, ws)
            except ConnectionClosed as e:
                code = e.rcvd.code if e.rcvd is not None else None
                out.append(Check(name, False, f"the socket closed ({code})"))
                break
            except (OSError, WebSocketException) as e:
                out.append(Check(name, False, f"{type(e).__name__}: {e}"))
                break
            out.append(Check(name, ok, detail))
    try:
        ws = d.connect()
        ws.send(d.frame())
        ok, detail = d.torque_for(ws, d.seq)
        ws.close()
        out.append(Check("reconnect", ok, detail))
    except (OSError, WebSocketException, TimeoutError) as e:
        out.append(Check("reconnect", False, f"{type(e).__name__}: {e}"))
    return out

"""A device's client of gaitscope's device protocol (``/ws/devices/{id}``, ``docs/api.md``), with a torque watchdog.

A device team gives it two functions, what its sensors read now and how to apply a torque, and runs it::

    from gaitscope.sessions.devices.client import DeviceClient

    client = DeviceClient(
        "ws://lab-server:8000/ws/devices/12", token="...", rate_hz=200.0,
        read_frame=lambda: {"foot_angle_deg": enc.foot(), "shank_angle_deg": enc.shank(), "heel_strike": fsr.hit()},
        apply_torque=motor.set_torque_Nm, max_torque_Nm=30.0,
    )
    client.run(stop)  # until stop (a threading.Event) is set; client.reports says what happened

Three threads, so that nothing on the network can hold the torque up:

- the **actuator** applies :class:`~gaitscope.sessions.devices.watchdog.TorqueWatchdog`'s output at the rate,
  whatever the sockets do: a reply late beyond the deadline, or a connection lost, takes the torque to zero
  at the watchdog's ramp; a stalled socket is then closed, so the sender and receiver stop waiting on it;
- the **sender** (the caller's thread) paces frames on the clock (``seq`` increasing, ``t`` the device's
  monotonic clock, ``sent_ns`` its wall clock), connects with the token, and reconnects with exponential
  backoff (``backoff_s`` doubling up to ``max_backoff_s``); after a trip it waits ``rejoin_pause_s`` (more
  than the server's ``MAX_GAP_S``, 1 s) before it rejoins, so the server restarts its estimators and ramps
  the torque up from zero through its own soft start (the watchdog follows replies again only then);
- the **receiver** reads replies: a ``TorqueCommand`` goes to the watchdog (an older ``seq`` than one taken is
  out of order and ignored), a ``DeviceNotice`` is counted and reported.

A ``read_frame`` that raises sends no frame (so the replies stop and the watchdog takes the torque off); an
``apply_torque`` that raises is reported (``actuator``) and called again at the next tick with the watchdog's
output: neither stops the client. A token the server refuses (HTTP 401 or 403 at the handshake, close code 1008
after) is reported and retried at the longest backoff: a revoked token does not turn into a flood of handshakes.
The device's reboot needs nothing: the server resynchronises a clock that restarts. Imports only the standard
library and ``websockets``.
"""

from __future__ import annotations

import contextlib
import json
import math
import socket
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Final

from websockets.exceptions import ConnectionClosed, InvalidStatus, WebSocketException
from websockets.sync.client import ClientConnection, connect

from gaitscope.sessions.devices.watchdog import TorqueWatchdog, WatchdogConfig, default_deadline_s

__all__ = ["REJOIN_PAUSE_S", "DeviceClient", "Report"]

#: Pause before rejoining after a trip (s): beyond the server's MAX_GAP_S (1 s), so its estimators restart.
REJOIN_PAUSE_S: Final = 1.5

Frame = Mapping[str, float | bool | None]


@dataclass(frozen=True)
class Report:
    """Something the client did or saw: at ``t`` (the device's clock, s), what (``connected``, ``tripped``,
    ``closed``, ``refused``, ``unreachable``, ``notice``, ``rejoin``), and the detail."""

    t: float
    kind: str
    detail: str = ""


@dataclass
class _Link:
    ws: ClientConnection | None = None
    seq: int = 0
    notices: dict[str, int] = field(default_factory=dict)


class DeviceClient:
    """See the module docstring.

    Args:
        url: ``ws://host:port/ws/devices/{session_id}`` (``wss://`` behind TLS).
        token: a device token of the session (``POST /api/sessions/{id}/device-tokens``).
        rate_hz: the rate the session declared; frames are paced at it.
        read_frame: the sensors now, as ``SensorFrame`` channels (``foot_angle_deg``, ...; None: not measured).
        apply_torque: sets the device's torque (N m); called at ``rate_hz`` with the watchdog's output.
        max_torque_Nm: the device's own limit: a reply above it is not valid.
        deadline_s: longest wait for a reply before the torque comes off (default: 10 periods, at least 50 ms).
        ramp_Nm_per_s: how fast it comes off.
        clock: the device's monotonic clock (s); tests inject one.
    """

    def __init__(
        self,
        url: str,
        token: str,
        *,
        rate_hz: float,
        read_frame: Callable[[], Frame],
        apply_torque: Callable[[float], None],
        max_torque_Nm: float = 80.0,
        deadline_s: float | None = None,
        ramp_Nm_per_s: float = 100.0,
        backoff_s: float = 0.25,
        max_backoff_s: float = 8.0,
        rejoin_pause_s: float = REJOIN_PAUSE_S,
        clock: Callable[[], float] = time.monotonic,
    ):
        if not url.startswith(("ws://", "wss://")):
            raise ValueError(f"url must be ws:// or wss://, got {url!r}")
        if not (math.isfinite(rate_hz) and 0 < rate_hz <= 1000):
            raise ValueError(f"rate_hz must lie in (0, 1000], got {rate_hz}")
        self.url, self.token, self.rate_hz = url, token, rate_hz
        self.read_frame, self.apply_torque, self.clock = read_frame, apply_torque, clock
        self.backoff_s, self.max_backoff_s, self.rejoin_pause_s = backoff_s, max_backoff_s, rejoin_pause_s
        deadline = default_deadline_s(rate_hz) if deadline_s is None else deadline_s
        self.watchdog = TorqueWatchdog(WatchdogConfig(deadline, ramp_Nm_per_s, max_torque_Nm))
        self.reports: list[Report] = []
        self.applied: list[tuple[float, float]] = []  # (t, torque) the actuator applied, the last 10 s
        self._lock = threading.Lock()
        self._link = _Link()

    # --- the caller's thread: connect, send, reconnect ---------------------------------------------------------
    def run(self, stop: threading.Event) -> None:
        """Stream until ``stop`` is set; the torque is zero when it returns."""
        actuator = threading.Thread(target=self._actuate, args=(stop,), name="device-actuator", daemon=True)
        actuator.start()
        wait = self.backoff_s
        try:
            while not stop.is_set():
                ws = self._connect()
                if ws is None:
                    stop.wait(wait)
                    wait = min(2 * wait, self.max_backoff_s)
                    continue
                wait = self.backoff_s
                receiver = threading.Thread(target=self._receive, args=(ws,), name="device-receiver", daemon=True)
                receiver.start()
                self._send(ws, stop)
                self._abort(ws)
                receiver.join(timeout=2.0)
                if not stop.is_set():
                    self._report(
                        "rejoin", f"rejoining after {self.rejoin_pause_s:g} s, through the server's soft start"
                    )
                    stop.wait(self.rejoin_pause_s)
        finally:
            stop.set()
            actuator.join(timeout=2.0)
            try:
                self.apply_torque(0.0)
            except Exception as e:
                self._apply_failed(e)

    def _connect(self) -> ClientConnection | None:
        headers = {"Authorization": f"Bearer {self.token}"}
        try:
            ws = connect(self.url, additional_headers=headers, open_timeout=5.0, close_timeout=1.0)
        except InvalidStatus as e:
            code = e.response.status_code
            if code in (401, 403):
                self._report(
                    "refused", f"the server refused the token (HTTP {code}); retrying every {self.max_backoff_s:g} s"
                )
                self.backoff_s = self.max_backoff_s  # a revoked token: no flood of handshakes
            else:
                self._report("refused", f"the handshake failed with HTTP {code}")
            return None
        except (OSError, WebSocketException, TimeoutError) as e:
            self._report("unreachable", f"{type(e).__name__}: {e}")
            return None
        with self._lock:
            self._link = _Link(ws)
            self.watchdog.rearm(self.clock())
        self._report("connected", self.url)
        return ws

    def _send(self, ws: ClientConnection, stop: threading.Event) -> None:
        """Frames at the rate until the link fails or the watchdog trips."""
        period = 1.0 / self.rate_hz
        due = self.clock()
        while not stop.is_set():
            with self._lock:
                if self.watchdog.state != "following" or self._link.ws is not ws:
                    return
                self._link.seq += 1
                seq = self._link.seq
            try:
                frame = {k: v for k, v in self.read_frame().items() if v is not None}
            except Exception as e:  # the sensors failed: no frame, so no reply, so the watchdog takes the torque off
                self._report("sensors", f"read_frame failed: {type(e).__name__}: {e}"[:300])
                stop.wait(period)
                continue
            message = {"type": "frame", "version": 2, "seq": seq, "t": self.clock(), "sent_ns": time.time_ns(), **frame}
            try:
                ws.send(json.dumps(message))
            except (ConnectionClosed, OSError) as e:
                self._trip(f"the connection failed while sending: {type(e).__name__}")
                return
            due += period
            late = self.clock() - due
            if late > 0.5:  # behind by more than half a second (a stall): move the schedule on, do not burst
                due = self.clock()
            stop.wait(max(0.0, due - self.clock()))

    # --- the receiver thread ----------------------------------------------------------------------------------
    def _receive(self, ws: ClientConnection) -> None:
        try:
            for raw in ws:
                now = self.clock()
                try:
                    msg = json.loads(raw)
                except (TypeError, ValueError):
                    continue
                if not isinstance(msg, dict):
                    continue
                if msg.get("type") == "torque" and isinstance(msg.get("seq"), int):
                    torque = msg.get("torque_Nm")
                    with self._lock:
                        if self._link.ws is ws and isinstance(torque, int | float):
                            self.watchdog.reply(now, msg["seq"], float(torque))
                elif msg.get("type") == "error":
                    kind = str(msg.get("kind", "?"))
                    with self._lock:
                        self._link.notices[kind] = self._link.notices.get(kind, 0) + 1
                        first = self._link.notices[kind] == 1
                    if first:
                        self._report("notice", f"{kind}: {str(msg.get('detail', ''))[:200]}")
        except ConnectionClosed as e:
            code = e.rcvd.code if e.rcvd is not None else None
            reason = e.rcvd.reason if e.rcvd is not None else ""
            self._report("closed", f"the server closed the connection ({code} {reason})".strip())
            if code == 1008 and "token" in reason.lower():
                self.backoff_s = self.max_backoff_s
            self._trip(f"the connection closed ({code})")
        except OSError as e:
            self._trip(f"the connection failed: {type(e).__name__}")

    # --- the actuator thread ----------------------------------------------------------------------------------
    def _actuate(self, stop: threading.Event) -> None:
        period = 1.0 / self.rate_hz
        while not stop.is_set():
            now = self.clock()
            with self._lock:
                was = self.watchdog.state
                torque = self.watchdog.output(now)
                tripped = was == "following" and self.watchdog.state == "tripped"
                ws = self._link.ws
            try:
                self.apply_torque(torque)
            except Exception as e:  # the device's own call failed: keep the watchdog running, say so, once per kind
                self._apply_failed(e)
            self.applied.append((now, torque))
            if len(self.applied) > 10 * self.rate_hz:
                del self.applied[: len(self.applied) // 2]
            if tripped:
                self._report("tripped", self.watchdog.reason or "")
                if ws is not None:
                    self._abort(ws)  # a stalled socket: unblock the sender and the receiver
            stop.wait(period)

    def _trip(self, reason: str) -> None:
        with self._lock:
            was = self.watchdog.state
            self.watchdog.trip(self.clock(), reason)
            now_tripped = was == "following"
        if now_tripped:
            self._report("tripped", reason)

    def _abort(self, ws: ClientConnection) -> None:
        """Close without waiting on the peer (a stalled one would hold a clean close for its timeout)."""
        with self._lock:
            if self._link.ws is ws:
                self._link.ws = None
        with contextlib.suppress(OSError):
            ws.socket.shutdown(socket.SHUT_RDWR)
        with contextlib.suppress(Exception):
            ws.socket.close()

    def _apply_failed(self, e: Exception) -> None:
        text = f"apply_torque failed: {type(e).__name__}: {e}"[:300]
        if not self.reports or self.reports[-1].detail != text:
            self._report("actuator", text)

    def _report(self, kind: str, detail: str = "") -> None:
        self.reports.append(Report(self.clock(), kind, detail))

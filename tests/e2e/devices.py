"""A simulated device streaming to a live session over the real websocket, for the e2e tests.

Each test module subclasses :class:`StreamingDevice` with what it sends (``stream``) and opens a session
for it with :func:`device_session`: subject, device session (its channels declared, its estimator stack
if given), a device token issued for it (issue #13: the device websocket refuses a connection without one),
the device thread started with it, and on the way out the device stopped and the session stopped.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Iterator
from typing import Any, TypeVar

from websockets.sync.client import connect
from websockets.sync.connection import Connection

from tests.e2e.accounts import call

#: How far behind its schedule a test device may fall before it moves it on (s; :meth:`StreamingDevice.pace`).
MAX_LATE_S = 0.5


class StreamingDevice(threading.Thread):
    """A device thread: ``stream(ws)`` sends until ``stop`` is set; an exception is kept in ``error``."""

    def __init__(self, base: str, session_id: int, token: str):
        super().__init__(daemon=True)
        self.url = base.replace("http://", "ws://") + f"/ws/devices/{session_id}"
        self.token = token
        self.stop = threading.Event()
        self.error: BaseException | None = None
        self._slip = 0.0  # s the schedule was moved on because the device fell behind it (:meth:`pace`)

    def stream(self, ws: Connection) -> None:
        raise NotImplementedError

    def pace(self, start: float, sent: int, rate_hz: float) -> None:
        """Wait until the next frame is due (``start + sent / rate_hz`` on ``time.monotonic()``): paced by the
        clock, not by a pause after each answer, the declared rate is kept whatever the round trip takes (a
        rate short by 10 % turns the health box amber). Returns at once when the device is stopped.

        A device more than :data:`MAX_LATE_S` behind its schedule (its thread or the server starved on a
        loaded machine) moves the schedule on rather than catching up at full speed: a catch-up longer than
        the server's burst allowance (2 s of frames) is over the declared rate, the server drops those frames
        without an answer (one rate notice a second), and a device waiting for each answer timed out."""
        due = start + self._slip + sent / rate_hz
        late = time.monotonic() - due
        if late > MAX_LATE_S:
            self._slip += late - MAX_LATE_S
        self.stop.wait(max(0.0, due - time.monotonic()))

    def run(self) -> None:
        try:
            with connect(self.url, additional_headers={"Authorization": f"Bearer {self.token}"}) as ws:
                self.stream(ws)
        except BaseException as e:
            self.error = e


D = TypeVar("D", bound=StreamingDevice)


@contextlib.contextmanager
def device_session(
    server: str, code: str, rate_hz: float, channels: list[str], device: type[D], estimators: list[str] | None = None
) -> Iterator[tuple[int, D]]:
    """A subject ``code``'s device session streamed by a started ``device``; stopped (if still running) after."""
    subject = call(server, "POST", "/api/subjects", {"code": code, "leg_length_m": 0.9, "mass_kg": 70.0})
    body: dict[str, Any] = {
        "subject_id": subject["id"],
        "source": {"kind": "device", "rate_hz": rate_hz, "channels": channels},
    }
    if estimators is not None:
        body["settings"] = {"estimators": estimators}
    session = call(server, "POST", "/api/sessions", body)
    token = call(server, "POST", f"/api/sessions/{session['id']}/device-tokens")["token"]
    streaming = device(server, session["id"], token)
    streaming.start()
    try:
        yield session["id"], streaming
    finally:
        streaming.stop.set()
        streaming.join(timeout=10)
        if call(server, "GET", f"/api/sessions/{session['id']}")["state"] == "running":
            call(server, "POST", f"/api/sessions/{session['id']}/stop")

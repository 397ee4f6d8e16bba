"""The device client against a real server (``gaitscope serve``, real sockets), through a proxy that injects the
faults of a clinic's network: a stalled socket, a slow link, the server gone, a revoked token; and the server
itself killed. In every one the watchdog takes the torque to zero within its deadline plus the ramp, the client
says why, and the torque comes back only through the server's soft start on a new connection.

Times here are the client's clock; the bounds hold as functions of it (the watchdog's output is one), with a
margin only for when the actuator thread got to run on a loaded machine.
"""

from __future__ import annotations

import itertools
import json
import socket
import threading
import time
import urllib.request
from collections.abc import Iterator
from typing import Any

import pytest

from gaitscope.server.bench.launch import RunningServer, start_server
from gaitscope.sessions.devices.client import DeviceClient, Report
from tests.device_tokens import device_session
from tests.walks import walk_frames

#: A real server over real sockets, fault after fault: tens of seconds.
pytestmark = pytest.mark.slow

RATE = 100.0
DEADLINE_S = 0.1  # the default at 100 Hz
RAMP = 100.0
#: How late the actuator thread may run on a loaded machine (s).
SLACK_S = 0.5


class FaultProxy:
    """A TCP proxy between the client and the server that can stall, slow or drop the link."""

    def __init__(self, target_port: int):
        self.target = target_port
        self.delay_s = 0.0
        self.stalled = threading.Event()
        self.down = threading.Event()
        self._conns: list[socket.socket] = []
        self._lock = threading.Lock()
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.port = self.listener.getsockname()[1]
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while True:
            try:
                client, _ = self.listener.accept()
            except OSError:
                return
            if self.down.is_set():
                client.close()
                continue
            try:
                upstream = socket.create_connection(("127.0.0.1", self.target), timeout=5)
            except OSError:
                client.close()
                continue
            with self._lock:
                self._conns += [client, upstream]
            threading.Thread(target=self._pipe, args=(client, upstream, False), daemon=True).start()
            threading.Thread(target=self._pipe, args=(upstream, client, True), daemon=True).start()

    def _pipe(self, src: socket.socket, dst: socket.socket, replies: bool) -> None:
        try:
            while data := src.recv(65536):
                while replies and self.stalled.is_set() and not self.down.is_set():
                    time.sleep(0.01)  # the replies sit in the network: a stalled socket
                if self.delay_s:
                    time.sleep(self.delay_s)
                dst.sendall(data)
        except OSError:
            pass
        finally:
            for s in (src, dst):
                try:
                    s.close()
                except OSError:
                    pass

    def drop(self) -> None:
        """Every connection cut, new ones refused until :meth:`restore`."""
        self.down.set()
        with self._lock:
            conns, self._conns = self._conns, []
        for s in conns:
            try:
                s.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass

    def restore(self) -> None:
        self.down.clear()
        self.stalled.clear()
        self.delay_s = 0.0


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningServer]:
    running = start_server(tmp_path_factory.mktemp("device-client"), "--no-leg-view", "--no-demo")
    try:
        yield running
    finally:
        running.stop()


def _session(base: str) -> tuple[int, str, int]:
    return device_session(base, f"DEV{time.monotonic_ns() % 10**6}", RATE)


class Device:
    """A simulated device: a walk's frames, looped, read at the rate; the torque it was told to apply."""

    def __init__(self, url: str, token: str):
        frames = itertools.cycle([f.model_dump(exclude_none=True, exclude={"seq", "t", "sent_ns", "version", "type"})
                                  for f in walk_frames(12, rate_hz=RATE)])  # fmt: skip
        self.torques: list[tuple[float, float]] = []
        self.client = DeviceClient(
            url, token, rate_hz=RATE, read_frame=lambda: next(frames), apply_torque=self._apply, max_torque_Nm=80.0
        )
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self.client.run, args=(self.stop,), daemon=True)

    def _apply(self, torque: float) -> None:
        self.torques.append((self.client.clock(), torque))

    def wait(self, what: str, check: Any, timeout: float = 20.0) -> None:
        deadline = time.monotonic() + timeout
        while not check():
            assert time.monotonic() < deadline, f"{what}: not within {timeout} s; reports {self.client.reports[-8:]}"
            time.sleep(0.02)

    def pushing(self, since: float = 0.0) -> bool:
        """Following replies, with the walk's push-off torque since ``since`` (over 5 N m: past the soft start's
        first second)."""
        return self.client.watchdog.state == "following" and any(
            tq > 5.0 for t, tq in self.torques[-200:] if t >= since
        )

    def reports_since(self, t0: float, kind: str) -> list[Report]:
        return [r for r in self.client.reports if r.t >= t0 and r.kind == kind]

    def off_in_time(self, t_fault: float) -> None:
        """Zero within the deadline plus the ramp from the torque last applied before the fault."""
        before = [tq for t, tq in self.torques if t <= t_fault]
        peak = max(before[-5:], default=0.0)
        bound = t_fault + DEADLINE_S + peak / RAMP + SLACK_S
        self.wait(
            "torque off", lambda: self.torques and self.torques[-1][1] == 0.0, timeout=bound - time.monotonic() + 5
        )
        late = [(t, tq) for t, tq in self.torques if t > bound and tq > 0.0 and t < t_fault + 5]
        assert not late, late[:5]
        trips = self.reports_since(t_fault, "tripped")
        assert trips, self.client.reports[-8:]
        ramp = [(t, tq) for t, tq in list(self.client.applied) if trips[0].t <= t <= bound]  # at the watchdog's times
        for (t0, a), (t1, b) in itertools.pairwise(ramp):  # from the trip on: down, and no faster than the ramp
            assert b <= a and a - b <= RAMP * (t1 - t0) + 1e-6, ((t0, a), (t1, b))

    def back_through_soft_start(self, t_rejoin: float) -> None:
        """After the rejoin, the torque rises from zero no faster than the server's soft start (10 N m/s of bound)."""
        self.wait("torque back", lambda: self.pushing(t_rejoin), timeout=30)
        after = [(t, tq) for t, tq in self.torques if t >= t_rejoin]
        assert after and after[0][1] == 0.0
        for t, tq in after:
            assert tq <= 10.0 * (t - t_rejoin) + 0.5, (t - t_rejoin, tq)
        assert max(tq for _, tq in after) > 5.0  # and it did come back


def test_every_fault_takes_the_torque_off_in_time_and_it_comes_back_through_the_soft_start(
    server: RunningServer,
) -> None:
    sid, token, token_id = _session(server.base)
    proxy = FaultProxy(server.port)
    device = Device(f"ws://127.0.0.1:{proxy.port}/ws/devices/{sid}", token)
    device.thread.start()
    try:
        device.wait("first torques", device.pushing, timeout=30)

        # a stalled socket: the replies stop coming
        t_fault = device.client.clock()
        proxy.stalled.set()
        device.off_in_time(t_fault)
        assert device.reports_since(t_fault, "tripped")[0].detail.startswith("no valid reply for")
        proxy.stalled.clear()
        device.wait("rejoined", lambda: device.reports_since(t_fault, "connected"))
        device.back_through_soft_start(device.reports_since(t_fault, "connected")[0].t)

        # a slow link: every packet 0.3 s late, past the 0.1 s deadline
        t_fault = device.client.clock()
        proxy.delay_s = 0.3
        device.off_in_time(t_fault)
        proxy.delay_s = 0.0
        device.wait("rejoined", lambda: device.reports_since(t_fault, "connected"), timeout=30)
        device.wait("pushing again", lambda: device.pushing(t_fault + 1.0), timeout=30)

        # the server gone (the network, or its machine): every connection cut, new ones refused
        t_fault = device.client.clock()
        proxy.drop()
        device.off_in_time(t_fault)
        device.wait("unreachable", lambda: device.reports_since(t_fault, "unreachable"))
        proxy.restore()
        device.wait("rejoined", lambda: device.reports_since(t_fault, "connected"), timeout=30)
        device.back_through_soft_start(device.reports_since(t_fault, "connected")[0].t)

        # the token revoked: the server closes the socket and refuses the next handshake
        t_fault = device.client.clock()
        req = urllib.request.Request(
            f"{server.base}/api/sessions/{sid}/device-tokens/{token_id}", data=b"", method="DELETE"
        )
        urllib.request.urlopen(req, timeout=10).close()
        device.off_in_time(t_fault)
        device.wait("refused", lambda: device.reports_since(t_fault, "refused"), timeout=30)
        assert "refused the token" in device.reports_since(t_fault, "refused")[0].detail
        assert device.client.watchdog.output(device.client.clock()) == 0.0
    finally:
        device.stop.set()
        device.thread.join(timeout=10)
    assert device.torques[-1][1] == 0.0  # stopped: the torque off


def test_the_server_killed_takes_the_torque_off(tmp_path: Any) -> None:
    running = start_server(tmp_path, "--no-leg-view", "--no-demo")
    try:
        sid, token, _ = _session(running.base)
        device = Device(f"ws://127.0.0.1:{running.port}/ws/devices/{sid}", token)
        device.thread.start()
        device.wait("first torques", device.pushing, timeout=30)
        t_fault = device.client.clock()
        running.stop()
        device.off_in_time(t_fault)
        device.wait("unreachable", lambda: device.reports_since(t_fault, "unreachable"))
    finally:
        running.stop()
        device.stop.set()
        device.thread.join(timeout=10)


def test_replies_out_of_order_are_ignored_and_notices_reported() -> None:
    client = DeviceClient(
        "ws://127.0.0.1:9/ws/devices/1", "t", rate_hz=RATE, read_frame=dict, apply_torque=lambda x: None
    )

    class Fake:
        def __iter__(self) -> Iterator[str]:
            yield json.dumps({"type": "torque", "seq": 5, "t": 0.0, "torque_Nm": 10.0})
            yield json.dumps({"type": "torque", "seq": 3, "t": 0.0, "torque_Nm": 30.0})  # late: an older frame's
            yield json.dumps({"type": "error", "kind": "rate", "detail": "over the declared rate"})
            yield json.dumps({"type": "error", "kind": "rate", "detail": "again"})
            yield "not json"

    fake = Fake()
    client._link.ws = fake  # type: ignore[assignment]
    client.watchdog.rearm(client.clock())
    client._receive(fake)  # type: ignore[arg-type]
    assert client.watchdog.output(client.clock()) == 10.0
    assert [r.detail for r in client.reports if r.kind == "notice"] == ["rate: over the declared rate"]
    assert client._link.notices == {"rate": 2}


def test_a_client_that_makes_no_sense_is_refused() -> None:
    for url, rate in (("http://x/ws/devices/1", 100.0), ("ws://x/ws/devices/1", 0.0), ("ws://x/ws/devices/1", 5000.0)):
        with pytest.raises(ValueError):
            DeviceClient(url, "t", rate_hz=rate, read_frame=dict, apply_torque=lambda x: None)


def test_a_failing_actuator_or_sensor_never_stops_the_client() -> None:
    calls: list[float] = []

    def apply(torque: float) -> None:
        calls.append(torque)
        raise OSError("motor driver timeout")

    def read() -> dict[str, float]:
        raise RuntimeError("encoder not found")

    client = DeviceClient("ws://127.0.0.1:9/ws/devices/1", "t", rate_hz=RATE, read_frame=read, apply_torque=apply)
    stop = threading.Event()
    thread = threading.Thread(target=client.run, args=(stop,), daemon=True)
    thread.start()
    deadline = time.monotonic() + 10
    while len(calls) < 20 and time.monotonic() < deadline:
        time.sleep(0.02)
    stop.set()
    thread.join(timeout=10)
    assert not thread.is_alive() and len(calls) >= 20  # the actuator went on calling, at the watchdog's zero
    assert set(calls) == {0.0}
    actuator = [r.detail for r in client.reports if r.kind == "actuator"]
    assert actuator and actuator[0] == "apply_torque failed: OSError: motor driver timeout"

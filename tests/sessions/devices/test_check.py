"""``gaitscope device-check``: passes against gaitscope's server, fails usefully against a broken endpoint."""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator

import pytest
from websockets.sync.server import ServerConnection, serve

from gaitscope.server.bench.launch import RunningServer, start_server
from gaitscope.server.cli import main
from gaitscope.sessions.devices.check import run_checks
from tests.load import post

#: A real server over real sockets.
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningServer]:
    running = start_server(tmp_path_factory.mktemp("device-check"), "--no-leg-view", "--no-demo")
    try:
        yield running
    finally:
        running.stop()


def test_the_server_passes_every_check(server: RunningServer, capsys: pytest.CaptureFixture[str]) -> None:
    subject = post(f"{server.base}/api/subjects", {"code": "CHK1", "leg_length_m": 0.9, "mass_kg": 70.0})
    session = post(
        f"{server.base}/api/sessions", {"subject_id": subject["id"], "source": {"kind": "device", "rate_hz": 100}}
    )
    token = post(f"{server.base}/api/sessions/{session['id']}/device-tokens", {})["token"]
    url = f"ws://127.0.0.1:{server.port}/ws/devices/{session['id']}"
    assert main(["device-check", "--rate", "100", "--", url, token]) == 0
    out = capsys.readouterr().out
    assert "FAIL" not in out and "11 of 11 checks passed" in out
    for name in ("bad token", "torque per frame", "invalid", "binary", "too large", "order", "reboot", "rate",
                 "malformed in a row", "reconnect"):  # fmt: skip
        assert f"PASS  {name}: " in out


def _broken(ws: ServerConnection) -> None:
    """An endpoint that takes any token, answers each frame with the wrong seq or a NaN torque, and never a notice."""
    for raw in ws:
        try:
            frame = json.loads(raw)
        except (TypeError, ValueError):
            continue
        seq = frame.get("seq", 0) if isinstance(frame, dict) else 0
        if seq % 2:
            ws.send(json.dumps({"type": "torque", "seq": seq, "t": 0.0, "torque_Nm": float("nan")}))
        else:
            ws.send(json.dumps({"type": "torque", "seq": seq + 1000, "t": 0.0, "torque_Nm": 1.0}))


def test_a_broken_endpoint_fails_saying_what_was_wrong(capsys: pytest.CaptureFixture[str]) -> None:
    with serve(_broken, "127.0.0.1", 0) as broken:
        threading.Thread(target=broken.serve_forever, daemon=True).start()
        port = broken.socket.getsockname()[1]
        assert main(["device-check", f"ws://127.0.0.1:{port}/ws/devices/1", "tok"]) == 1
        broken.shutdown()
    out = capsys.readouterr().out
    assert "FAIL  bad token: a wrong token opened the socket" in out
    assert "FAIL  torque per frame: frame 1: torque_Nm nan is not a finite number in [0, 80]" in out
    assert "FAIL  invalid: no 'invalid' notice" in out and "checks passed; failed: " in out


def test_nothing_listening_fails_the_handshake() -> None:
    checks = run_checks("ws://127.0.0.1:9/ws/devices/1", "tok")
    assert [c.name for c in checks] == ["bad token", "handshake"]
    assert not any(c.passed for c in checks)

"""Crash recovery: kill a recording server, restart it on the same data, and the recording is readable."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from server.app import create_app
from server.settings import Settings
from sessions.errors import DataFormatError
from sessions.mcap_io import check_mcap, read_messages


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_killed_server_leaves_a_recording_that_restart_recovers(tmp_path: Path) -> None:
    data = tmp_path / "data"
    port = _free_port()
    exe = str(Path(sys.executable).with_name("gaitscope"))
    proc = subprocess.Popen(
        [exe, "serve", "--data-dir", str(data), "--port", str(port), "--no-leg-view"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            try:
                urllib.request.urlopen(f"http://127.0.0.1:{port}/api/health", timeout=1)
                break
            except OSError:
                time.sleep(0.2)
        else:
            pytest.fail("server did not start")
        time.sleep(4.0)  # the demo session records at 200 Hz: several chunks on disk
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    files = list((data / "recordings").glob("*.mcap"))
    assert len(files) == 1
    with pytest.raises(DataFormatError, match="not finished"):
        check_mcap(files[0])

    with TestClient(create_app(Settings(data_dir=data, demo=False, leg_view=False))) as client:
        trial = client.get("/api/trials").json()[0]
        assert trial["status"] == "recovered" and trial["samples"] > 200  # > 1 s of the ~4 s kept
        check_mcap(files[0])
        times = [t for _, t, _ in read_messages(files[0], ["/gait_state"])]
        assert times == sorted(times)
        session = client.get("/api/sessions/1").json()
        assert session["state"] == "stopped"
        events = client.get("/api/sessions/1/events").json()
        assert events[-1]["kind"] == "system" and "server restarted" in events[-1]["text"]
        series = client.get(f"/api/trials/{trial['id']}/series?max_points=100").json()
        assert len(series["t"]) > 10

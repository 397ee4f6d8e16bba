"""Crash recovery: kill a recording server, restart it on the same data, and the recording is readable."""

from __future__ import annotations

import os
import signal
import time
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from server.app import create_app
from server.launch import start_server
from server.settings import Settings
from sessions.errors import DataFormatError
from sessions.mcap_io import check_mcap, read_messages


def test_killed_server_leaves_a_recording_that_restart_recovers(tmp_path: Path) -> None:
    data = tmp_path / "data"
    server = start_server(data, "--no-leg-view", timeout=60)
    try:
        time.sleep(4.0)  # the demo session records at 200 Hz: several chunks on disk
    finally:
        os.kill(server.proc.pid, signal.SIGKILL)
        server.proc.wait(timeout=10)
    files = list((data / "recordings").glob("*.mcap"))
    assert len(files) == 1
    with pytest.raises(DataFormatError, match="not finished"):
        check_mcap(files[0])

    settings = Settings(data_dir=data, demo=False, leg_view=False, allowed_hosts=["testserver"])  # TestClient's Host
    with TestClient(create_app(settings)) as client:
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

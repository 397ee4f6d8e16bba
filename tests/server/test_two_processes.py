"""Scale-out: two ``gaitscope serve`` processes on one PostgreSQL database and one data folder (issue #13).

Each process runs its own sessions; the database and the recordings are shared. What one process
writes, the other reads at once: a subject made on A is listed on B, and the trial a session recorded
on B is listed on A, with its events, and A reads its recording from the shared folder.

Runs only against PostgreSQL (``GAITSCOPE_TEST_POSTGRES``, ``scripts/postgres.sh``): one SQLite file
shared by two servers is not a supported deployment.
"""

from __future__ import annotations

import json
import os
import urllib.error
import urllib.request
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pytest

from gaitscope.server.bench.launch import RunningServer, start_server
from tests.load import session_time

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(
        not os.environ.get("GAITSCOPE_TEST_POSTGRES"),
        reason="GAITSCOPE_TEST_POSTGRES is not set (bash scripts/postgres.sh .venv/bin/python -m pytest ...)",
    ),
]


def _call(server: RunningServer, method: str, path: str, body: Any = None) -> Any:
    """One JSON request; the decoded answer, or the test fails with the status and the server's detail."""
    data = None if body is None else json.dumps(body).encode()
    request = urllib.request.Request(f"{server.base}{path}", data=data, method=method)
    if data is not None:
        request.add_header("Content-Type", "application/json")
    try:
        with urllib.request.urlopen(request, timeout=30) as r:
            return json.loads(r.read())
    except urllib.error.HTTPError as e:
        pytest.fail(f"{method} {path} on port {server.port}: {e.code} {e.read().decode()[:500]}")


@pytest.fixture
def servers(tmp_path: Path, database_url: str) -> Iterator[tuple[RunningServer, RunningServer]]:
    """A and B: two servers on one database and one data folder, started side by side."""
    data = tmp_path / "data"
    env = {**os.environ, "GAITSCOPE_DATABASE_URL": database_url}
    logs = [(tmp_path / f"server_{name}.log").open("wb") for name in "AB"]
    started: list[RunningServer] = []

    def start(log: Any) -> RunningServer:
        server = start_server(data, "--no-demo", "--no-leg-view", env=env, output=log, timeout=180)
        started.append(server)
        return server

    try:
        with ThreadPoolExecutor(2) as pool:
            a, b = pool.map(start, logs)
        yield a, b
    except RuntimeError as e:
        for log in logs:
            log.flush()
        pytest.fail(f"{e}\n" + "\n".join(p.read_text()[-2000:] for p in sorted(tmp_path.glob("server_*.log"))))
    finally:
        for server in started:
            server.stop()
        for log in logs:
            log.close()


def test_each_server_sees_the_others_subjects_and_trials(
    servers: tuple[RunningServer, RunningServer], tmp_path: Path
) -> None:
    a, b = servers
    assert a.proc.pid != b.proc.pid
    assert (tmp_path / "data").is_dir() and not (tmp_path / "data" / "gaitscope.db").exists()  # PostgreSQL, not a file

    subject = _call(a, "POST", "/api/subjects", {"code": "TWO01", "leg_length_m": 0.9, "mass_kg": 70.0})
    assert subject in _call(b, "GET", "/api/subjects")

    source = {"kind": "simulated", "rate_hz": 100.0}
    session = _call(b, "POST", "/api/sessions", {"subject_id": subject["id"], "source": source})
    assert session["state"] == "running"
    assert _call(a, "GET", f"/api/sessions/{session['id']}") == session  # A knows it, though B runs it
    trial = _call(b, "POST", f"/api/sessions/{session['id']}/recording", {"action": "start", "name": "on B"})
    session_time(b.base, session["id"], session_time(b.base, session["id"]) + 2.0)  # 2 s of it recorded
    trial = _call(b, "POST", f"/api/sessions/{session['id']}/recording", {"action": "stop"})
    stopped = _call(b, "POST", f"/api/sessions/{session['id']}/stop")
    assert stopped["state"] == "stopped"
    assert trial["status"] == "finished" and trial["samples"] > 0, trial

    assert trial in _call(a, "GET", "/api/trials")
    assert _call(a, "GET", f"/api/trials/{trial['id']}") == trial
    assert _call(a, "GET", f"/api/sessions/{session['id']}")["state"] == "stopped"
    events = _call(a, "GET", f"/api/trials/{trial['id']}/events")
    assert events == _call(b, "GET", f"/api/trials/{trial['id']}/events")
    series = _call(a, "GET", f"/api/trials/{trial['id']}/series")  # the recording, read by A off the shared folder
    times = series["t"]
    assert len(times) > 10 and times == sorted(times)
    assert 1.0 < times[-1] - times[0] < 10.0, (times[0], times[-1])

    # And back: what A writes now, B reads (no process caches the other's rows).
    note = _call(a, "POST", f"/api/trials/{trial['id']}/annotations", {"t": 0.5, "text": "seen on A"})
    assert note in _call(b, "GET", f"/api/trials/{trial['id']}/annotations")

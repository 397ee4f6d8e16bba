"""Crash recovery: kill a recording server, restart it on the same data; every recording is readable or
marked damaged, and every trial and session ends in a final state."""

from __future__ import annotations

import os
import shutil
import signal
import time
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from gaitscope.server.app import create_app
from gaitscope.server.bench.launch import start_server
from gaitscope.server.settings import Settings
from gaitscope.sessions import schema
from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.formats.mcap_io import check_mcap, read_messages, recover
from gaitscope.sessions.formats.recording import Recorder
from gaitscope.sessions.store import Store
from tests.waiting import wait_until

#: A real server over real sockets: seconds per test, and timing depends on the machine's load.
pytestmark = pytest.mark.slow

#: Trial statuses that nothing changes any more (``recording`` is the only other one).
FINAL = {"finished", "recovered", "uploaded", "damaged"}
START_NS = 1_700_000_000_000_000_000


NODE = "recovery-test-node"


def settings_for(data: Path) -> Settings:
    return Settings(data_dir=data, demo=False, leg_view=False, allowed_hosts=["testserver"], node=NODE)


def _states_on_disk(data: Path, scratch: Path) -> int:
    """How many gait states of the server's recording are on disk now (a copy, recovered as after a crash)."""
    files = list((data / "recordings").glob("*.mcap"))
    if not files:
        return 0
    copy = scratch / "on-disk.mcap"
    shutil.copyfile(files[0], copy)
    try:
        recover(copy)
    except (DataFormatError, OSError):  # no complete chunk yet
        return 0
    return sum(1 for _ in read_messages(copy, ["/gait_state"]))


def test_killed_server_loses_at_most_a_second_and_restart_recovers(tmp_path: Path) -> None:
    data = tmp_path / "data"
    # the restarted server is the same node (a supervisor restarts it on its port; here another port, so named)
    server = start_server(data, "--no-leg-view", env={**os.environ, "GAITSCOPE_NODE": NODE}, timeout=60)
    try:  # the demo session records at 200 Hz: several chunks on disk
        wait_until(lambda: _states_on_disk(data, tmp_path) >= 600, 60, "3 s of gait states on disk", interval=0.25)
    finally:
        killed_ns = time.time_ns()
        os.kill(server.proc.pid, signal.SIGKILL)
        server.proc.wait(timeout=10)
    files = list((data / "recordings").glob("*.mcap"))
    assert len(files) == 1
    with pytest.raises(DataFormatError, match="not finished"):
        check_mcap(files[0])

    with TestClient(create_app(settings_for(data))) as client:
        trials = client.get("/api/trials").json()
        assert [t["status"] for t in trials] == ["recovered"]
        trial = trials[0]
        assert trial["samples"] > 200  # > 1 s of the ~4 s kept
        check_mcap(files[0])
        states = [(lt, m) for _, lt, m in read_messages(files[0], ["/gait_state"])]
        assert [lt for lt, _ in states] == sorted(lt for lt, _ in states)
        # recv_ns is the server's wall clock when the last kept sample arrived: everything that
        # arrived after it, until the kill, was lost. (The log time, start + t, would not do: the
        # simulated source's clock starts about a second after the session's.)
        lost_s = (killed_ns - states[-1][1]["recv_ns"]) / 1e9
        assert 0.0 <= lost_s <= 1.0, f"kill -9 lost {lost_s:.3f} s"
        session = client.get("/api/sessions/1").json()
        assert session["state"] == "stopped"
        # intent events (the simulated walker's) may come at any time, even after the last sample kept
        events = [e for e in client.get("/api/sessions/1/events").json() if e["kind"] != "intent"]
        assert events[-2]["kind"] == "system" and events[-2]["text"].startswith(
            f"server restarted: the recording of {trial['name']} was interrupted and has been recovered ("
        )
        assert events[-1]["kind"] == "system" and events[-1]["text"] == "server restarted: session stopped"
        assert events[-1]["t"] == events[-2]["t"] == states[-1][1]["t"]  # the end of the session's timeline
        series = client.get(f"/api/trials/{trial['id']}/series?max_points=100").json()
        assert len(series["t"]) > 10


def _gait_state(i: int) -> schema.GaitState:
    return schema.GaitState(
        seq=i, t=i / 200, phase=0.0, phase_rate=1.0, stride_length_m=1.2, incline_deg=0.0, torque_Nm=0.0,
        tbe_phase=0.0, heel_strike=False, backup_reset=False, foot_angle_deg=None, shank_angle_deg=None,
        thigh_angle_deg=None, foot_pred_deg=0.0, shank_pred_deg=0.0, recv_ns=START_NS,
    )  # fmt: skip


def _unfinished_recording(path: Path, samples: int) -> None:
    """What a crash leaves after ``samples`` gait states: the file as it was before ``finish``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    full = path.with_suffix(".full")
    with Recorder(full, START_NS, {}) as rec:
        for i in range(samples):
            rec.write("/gait_state", i / 200, _gait_state(i))
        shutil.copyfile(full, path)
    full.unlink()


def test_startup_ends_every_trial_and_session_a_crash_left_open(tmp_path: Path) -> None:
    data = tmp_path / "data"
    data.mkdir()
    store = Store(settings_for(data).database_url)
    subject = store.create_subject(schema.SubjectCreate(code="S01", leg_length_m=0.9, mass_kg=70.0))
    live = store.create_session(schema.SessionCreate(subject_id=subject.id, start=False))
    rel = {name: f"recordings/{name}.mcap" for name in ("walk", "missing", "garbage", "done", "replayed")}
    walk = store.create_trial(live.id, "walk", rel["walk"])
    _unfinished_recording(data / rel["walk"], samples=700)  # 3.5 s; chunks close every 0.5 s
    store.create_trial(live.id, "missing", rel["missing"])  # no file at all
    store.create_trial(live.id, "garbage", rel["garbage"])
    (data / rel["garbage"]).write_bytes(b"time_s,foot_angle_deg\n0.0,1.0\n")  # not MCAP
    done = store.create_trial(live.id, "done", rel["done"])
    store.finish_trial(done.id, "finished", 10, 0.05)  # finished before the crash: left alone
    store.add_event(live.id, t=2.0, kind="annotation", text="trip")
    replay = store.create_session(
        schema.SessionCreate(subject_id=subject.id, source=schema.ReplaySource(trial_id=walk.id), start=False)
    )
    store.create_trial(replay.id, "replayed", rel["replayed"])
    _unfinished_recording(data / rel["replayed"], samples=300)
    for session in (live, replay):
        store.set_session_state(session.id, "running")
    store.close()

    with TestClient(create_app(settings_for(data))) as client:
        trials = {t["name"]: t for t in client.get("/api/trials").json()}
        assert {name: t["status"] for name, t in trials.items()} == {
            "walk": "recovered",
            "missing": "damaged",
            "garbage": "damaged",
            "done": "finished",
            "replayed": "recovered",
        }
        # A crash loses at most the open chunk: 0.5 s of data and the sample that would close it.
        walked = trials["walk"]["samples"]
        assert 700 - 101 <= walked < 700 and trials["walk"]["duration_s"] == pytest.approx((walked - 1) / 200)
        assert 300 - 101 <= trials["replayed"]["samples"] < 300
        assert (trials["done"]["samples"], trials["missing"]["samples"]) == (10, 0)
        assert (data / rel["garbage"]).read_bytes() == b"time_s,foot_angle_deg\n0.0,1.0\n"  # kept as it was
        assert {s["state"] for s in client.get("/api/sessions").json()} == {"stopped"}

        events = client.get(f"/api/sessions/{live.id}/events").json()
        system = [(e["t"], e["text"]) for e in events if e["kind"] == "system"]
        end = (walked - 1) / 200  # every event of the restart goes at the end of the session's timeline
        assert system == [
            (
                end,
                f"server restarted: the recording of walk was interrupted and has been recovered "
                f"({end:.1f} s kept; the last half second before the interruption may be missing)",
            ),
            (end, "server restarted: the recording of missing is lost: its file is missing"),
            (end, "server restarted: the recording of garbage is lost: its file is damaged beyond repair"),
            (end, "server restarted: session stopped"),
        ]
        assert events[-1]["text"] == "server restarted: session stopped"  # the end of its timeline
        assert all(str(tmp_path) not in e["text"] and ".mcap" not in e["text"] for e in events)
        missing_events = client.get(f"/api/trials/{trials['missing']['id']}/events").json()
        assert [e["text"] for e in missing_events] == [system[1][1]]
        replay_events = client.get(f"/api/sessions/{replay.id}/events").json()
        assert [e["text"] for e in replay_events][-1] == "server restarted: session stopped"
        assert client.get(f"/api/trials/{trials['walk']['id']}/series?max_points=100").json()["t"][-1] == system[-1][0]
        before = client.get(f"/api/sessions/{live.id}/events").json()

    with TestClient(create_app(settings_for(data))) as client:  # a second restart changes nothing
        assert {t["name"]: t["status"] for t in client.get("/api/trials").json()} == {
            name: t["status"] for name, t in trials.items()
        }
        assert client.get(f"/api/sessions/{live.id}/events").json() == before
        assert all(t["status"] in FINAL for t in client.get("/api/trials").json())


def test_a_restart_leaves_another_nodes_running_session_alone(tmp_path: Path) -> None:
    """Two processes on one database: a process that starts recovers its own sessions, not another's, and
    refuses to stop another's."""
    data = tmp_path / "data"
    store = Store(settings_for(data).database_url)
    subject = store.create_subject(schema.SubjectCreate(code="N1", leg_length_m=0.9, mass_kg=70.0))
    mine, theirs = (store.create_session(schema.SessionCreate(subject_id=subject.id, start=False)) for _ in range(2))
    store.set_session_state(mine.id, "running", NODE)
    store.set_session_state(theirs.id, "running", "other-host:8000")
    store.create_trial(theirs.id, "theirs", "recordings/theirs.mcap")
    store.close()
    with TestClient(create_app(settings_for(data))) as client:
        states = {s["id"]: (s["state"], s["node"]) for s in client.get("/api/sessions").json()}
        assert states == {mine.id: ("stopped", NODE), theirs.id: ("running", "other-host:8000")}
        assert [t["status"] for t in client.get("/api/trials").json()] == ["recording"]  # theirs, still recording
        r = client.post(f"/api/sessions/{theirs.id}/stop")
        assert r.status_code == 409 and "runs on other-host:8000: stop it there" in r.json()["detail"]
        r = client.patch(f"/api/sessions/{theirs.id}/settings", json={"torque_gain": 1.2, "confirm": True})
        assert r.status_code == 409 and "runs on other-host:8000, not on this server" in r.json()["detail"]

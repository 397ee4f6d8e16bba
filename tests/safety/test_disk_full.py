"""A disk that fills up while a session records: the API tells the truth and never answers 500.

Reproduces: another process filled the disk while recording; the session stopped and the device was told,
but the database still said running and recording, stop answered 500, settings 409, and the trial stayed
"recording" with an unreadable file until a restart.

Two ways in: a real full file system (a small tmpfs filled by a "runaway" file: needs root, which CI has;
skipped otherwise), and the same failure injected at the file and database layers (always runs).
"""

from __future__ import annotations

import contextlib
import errno
import io
import json
import math
import os
import re
import sqlite3
import subprocess
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, Any

import pytest
from fastapi.testclient import TestClient
from sqlalchemy.exc import OperationalError
from starlette.websockets import WebSocketDisconnect

from gaitscope.server.app import create_app
from gaitscope.server.settings import Settings
from gaitscope.sessions.formats.mcap_io import read_messages, recover, recover_in_place
from gaitscope.sessions.formats.recording import Recorder
from gaitscope.sessions.live.manager import SessionManager
from tests.device_tokens import device_path
from tests.waiting import wait_until

#: Session time (s) streamed before the disk fills: several chunks on file.
BEFORE_S = 2.0


def full(*_: object, **__: object) -> None:
    """A store method on a full disk: what SQLAlchemy raises for SQLite's SQLITE_FULL."""
    raise OperationalError("UPDATE ...", None, sqlite3.OperationalError("database or disk is full"))


def _walk(k: int) -> dict[str, Any]:
    t = 0.005 * k
    w = 2 * math.pi * t
    return {"type": "frame", "seq": k, "t": t, "foot_angle_deg": 25 * math.sin(w),
            "foot_vel_dps": 157 * math.cos(w), "shank_angle_deg": 20 * math.sin(w - 0.4),
            "shank_vel_dps": 126 * math.cos(w - 0.4)}  # fmt: skip


def _session(client: TestClient) -> int:
    r = client.post("/api/subjects", json={"code": "FULL1", "leg_length_m": 0.9, "mass_kg": 80})
    assert r.status_code == 201, r.text
    body = {"subject_id": r.json()["id"], "source": {"kind": "device", "rate_hz": 200.0}}
    r = client.post("/api/sessions", json=body)
    assert r.status_code == 201, r.text
    sid = int(r.json()["id"])
    client.app.state.ctx.manager.get(sid).disk_check = lambda: "ok"  # type: ignore[attr-defined]  # sudden: unseen
    return sid


def _stream_until_closed(client: TestClient, sid: int, first: int, fill: Callable[[], None]) -> str:
    """Stream BEFORE_S of walking, call ``fill``, and stream on until the server ends the session (at most
    10 s of session time); returns the close reason the device got."""
    with client.websocket_connect(device_path(client, sid)) as ws:
        before = round(BEFORE_S / 0.005)
        for k in range(first, first + before):
            ws.send_text(json.dumps(_walk(k)))
            assert json.loads(ws.receive_text())["type"] == "torque"
        fill()
        with pytest.raises(WebSocketDisconnect) as closed:
            for k in range(first + before, first + before + 2000):
                ws.send_text(json.dumps(_walk(k)))
                ws.receive_text()
    return str(closed.value.reason)


def _check_the_api_tells_the_truth(client: TestClient, sid: int, disk_full: bool) -> dict[str, Any]:
    """While the disk is full: the session stopped, the trial readable, every action 507 or 409 with a reason."""
    session = client.get(f"/api/sessions/{sid}").json()
    assert session["state"] == "stopped", session
    [trial] = client.get(f"/api/trials?session_id={sid}").json()
    assert trial["status"] == "recovered", trial
    assert 0 < trial["samples"] <= 2000 and trial["duration_s"] > BEFORE_S - 1.0
    series = client.get(f"/api/trials/{trial['id']}/series?max_points=5000")
    assert series.status_code == 200, series.text
    t = series.json()["t"]
    assert len(t) == trial["samples"] and t[-1] >= BEFORE_S - 1.0  # up to its last complete chunk
    answers = {
        "stop": client.post(f"/api/sessions/{sid}/stop"),
        "settings": client.patch(f"/api/sessions/{sid}/settings", json={"torque_gain": 0.9}),
        "annotate": client.post(f"/api/sessions/{sid}/annotations", json={"text": "full"}),
        "subject": client.post("/api/subjects", json={"code": "FULL2", "leg_length_m": 0.9, "mass_kg": 80}),
        "session": client.post("/api/sessions", json={"subject_id": session["subject_id"]}),
        "recording": client.post(f"/api/sessions/{sid}/recording", json={"action": "start"}),
    }
    # A database on another disk (PostgreSQL here) still has room: what only it stores is stored.
    stored_elsewhere = () if disk_full else ("annotate", "subject")
    for what, r in answers.items():
        if what in stored_elsewhere:
            assert r.status_code == 201, (what, r.status_code, r.text)
            continue
        assert r.status_code in (409, 507), (what, r.status_code, r.text)
        detail = r.json()["detail"]
        assert re.search(r"disk is (almost )?full|not running", detail), (what, r.text)
    assert answers["settings"].status_code == 409  # why: the full disk while its end is not stored, else "not running"
    assert ("disk is full" if disk_full else "is not running") in answers["settings"].json()["detail"]
    if disk_full:  # the database cannot write: nothing new can be stored
        for what in ("annotate", "subject", "session"):
            assert answers[what].status_code == 507, (what, answers[what].text)
            assert "free space on the server's data disk" in answers[what].json()["detail"]
    return trial


def _check_stored_once_there_is_room(client: TestClient, sid: int, trial: dict[str, Any]) -> None:
    manager: SessionManager = client.app.state.ctx.manager  # type: ignore[attr-defined]
    assert manager.reconcile() and not manager.unsaved
    store = client.app.state.ctx.store  # type: ignore[attr-defined]
    assert store.get_session(sid).state == "stopped"
    stored = store.get_trial(trial["id"])
    assert (stored.status, stored.samples) == ("recovered", trial["samples"])
    texts = [e.text for e in store.list_events(sid)]
    assert any(t.startswith("session stopped:") and "disk is full" in t for t in texts), texts
    assert any(t.startswith(f"the recording of {trial['name']} could not be finished") for t in texts), texts
    assert client.post(f"/api/sessions/{sid}/stop").status_code == 409  # stopped, as stored


# --- a real full file system ------------------------------------------------------------------------


@contextlib.contextmanager
def _tmpfs(folder: Path, size_mb: int) -> Iterator[Path]:
    folder.mkdir()
    if os.geteuid() != 0:
        pytest.skip("mounting a small tmpfs needs root (CI runs as root); the injected test below covers this")
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size_mb}m", "tmpfs", str(folder)],
                       capture_output=True, check=False)  # fmt: skip
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {r.stderr.decode().strip()}")
    try:
        yield folder
    finally:
        subprocess.run(["umount", "-l", str(folder)], capture_output=True, check=False)


def _fill(folder: Path) -> Path:
    """Fill the file system holding ``folder`` to its last byte, as a runaway process would."""
    filler = folder / "runaway.log"
    with open(filler, "ab", buffering=0) as f:
        for block in (1 << 20, 4096, 512, 1):
            with contextlib.suppress(OSError):
                while True:
                    f.write(b"\0" * block)
    return filler


def test_a_real_disk_filling_up_while_recording(tmp_path: Path) -> None:
    with _tmpfs(tmp_path / "disk", 24) as disk:
        settings = Settings(
            data_dir=disk / "data", demo=False, leg_view=False, allowed_hosts=["testserver"],
            disk_warn_mb=1, disk_stop_mb=1, upload_min_free_mb=1,
        )  # fmt: skip
        with TestClient(create_app(settings)) as client:
            sid = _session(client)
            if settings.database_url.startswith("sqlite"):  # the WAL empty: any write must grow a file
                store = client.app.state.ctx.store  # type: ignore[attr-defined]
                with store._engine.connect() as c:
                    c.exec_driver_sql("PRAGMA wal_checkpoint(TRUNCATE)")
            fillers: list[Path] = []
            reason = _stream_until_closed(client, sid, 0, lambda: fillers.append(_fill(disk)))
            assert "disk is full" in reason
            fillers.append(_fill(disk))  # the runaway process takes whatever the recovery freed
            trial = _check_the_api_tells_the_truth(client, sid, disk_full=settings.database_url.startswith("sqlite"))
            fillers[0].unlink()  # the runaway process stopped and its file deleted
            _check_stored_once_there_is_room(client, sid, trial)


# --- the same failure injected -----------------------------------------------------------------------


class _FullFile(io.FileIO):
    """A recording's file on a disk that fills up: writes refused with ENOSPC once ``full`` is set."""

    full = False

    def write(self, data: Any, /) -> int:
        if _FullFile.full:
            raise OSError(errno.ENOSPC, "No space left on device")
        return super().write(data)


def test_a_disk_full_injected_at_the_file_and_the_database(
    client: TestClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    sid = _session(client)
    runtime = client.app.state.ctx.manager.get(sid)  # type: ignore[attr-defined]
    recorder = runtime.recorder
    path = recorder.path
    recorder._file.close()
    recorder._file = _FullFile(path, "r+b")
    recorder._file.seek(0, io.SEEK_END)
    store = client.app.state.ctx.store  # type: ignore[attr-defined]


    def fill() -> None:
        _FullFile.full = True
        for name in ("finish_trial", "set_session_state", "add_event", "create_subject", "create_session",
                     "create_trial"):  # fmt: skip
            monkeypatch.setattr(store, name, full)
        monkeypatch.setattr("gaitscope.sessions.formats.mcap_io.atomic_output", _no_room_for_a_copy)

    try:
        reason = _stream_until_closed(client, sid, 0, fill)
    finally:
        _FullFile.full = False
    assert "disk is full" in reason
    assert store.get_session(sid).state == "running"  # the database could not take it ...
    trial = _check_the_api_tells_the_truth(client, sid, disk_full=True)  # ... the API says what is
    monkeypatch.undo()
    _check_stored_once_there_is_room(client, sid, trial)
    assert sum(1 for _ in read_messages(path, ["/gait_state"])) == trial["samples"]


@contextlib.contextmanager
def _no_room_for_a_copy(path: Path) -> Iterator[Path]:
    raise OSError(errno.ENOSPC, "No space left on device")
    yield path  # pragma: no cover


def test_a_running_session_stopped_while_the_database_is_full_is_stopped_with_507(
    client: TestClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    sid = _session(client)
    store = client.app.state.ctx.store  # type: ignore[attr-defined]
    with client.websocket_connect(device_path(client, sid)) as ws:
        for k in range(200):
            ws.send_text(json.dumps(_walk(k)))
            ws.receive_text()


    with monkeypatch.context() as m:
        for name in ("finish_trial", "set_session_state", "add_event"):
            m.setattr(store, name, full)
        r = client.post(f"/api/sessions/{sid}/stop")
        assert r.status_code == 507, r.text
        assert r.json()["detail"].startswith(f"session {sid} stopped, but the database could not store that")
        assert client.get(f"/api/sessions/{sid}").json()["state"] == "stopped"
        [trial] = client.get(f"/api/trials?session_id={sid}").json()
        assert (trial["status"], trial["samples"]) == ("finished", 200)
        again = client.post(f"/api/sessions/{sid}/stop")
        assert again.status_code == 507 and f"session {sid} is already stopped" in again.json()["detail"]
        annotate = client.post(f"/api/sessions/{sid}/annotations", json={"text": "x"})
        assert annotate.status_code == 507 and "disk is full" in annotate.json()["detail"]
    manager = client.app.state.ctx.manager  # type: ignore[attr-defined]
    # stored by the manager's retries (every RETRY_S), no call needed
    wait_until(lambda: not manager.unsaved, 10.0, "the manager's unsaved writes stored")
    assert store.get_session(sid).state == "stopped" and store.get_trial(trial["id"]).status == "finished"
    assert client.post(f"/api/sessions/{sid}/stop").status_code == 409


def test_a_stop_whose_audit_entry_the_full_database_refuses_still_stops(
    client: TestClient, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Stopping takes the assistance off the person: a full disk that refuses its audit entry does not refuse it."""
    sid = _session(client)
    ctx = client.app.state.ctx  # type: ignore[attr-defined]
    with client.websocket_connect(device_path(client, sid)) as ws:
        for k in range(50):
            ws.send_text(json.dumps(_walk(k)))
            ws.receive_text()
        with monkeypatch.context() as m:
            m.setattr(ctx.audit, "record", full)
            r = client.post(f"/api/sessions/{sid}/stop")
        assert r.status_code == 507, r.text
        assert r.json()["detail"].startswith(f"session {sid} stopped, but its audit entry could not be written")
        assert ctx.manager.get(sid) is None
        assert client.get(f"/api/sessions/{sid}").json()["state"] == "stopped"
        with pytest.raises(WebSocketDisconnect):  # the device is told
            ws.send_text(json.dumps(_walk(50)))
            ws.receive_text()


def test_an_annotation_the_full_database_refuses_is_507(client: TestClient, monkeypatch: pytest.MonkeyPatch) -> None:
    sid = _session(client)
    store = client.app.state.ctx.store  # type: ignore[attr-defined]


    monkeypatch.setattr(store, "add_event", full)
    r = client.post(f"/api/sessions/{sid}/annotations", json={"text": "x"})
    assert r.status_code == 507 and r.json()["detail"].startswith("the annotation was not saved: the server's disk")


# --- indexing a file where it lies ---------------------------------------------------------------------


def _unfinished(path: Path, seconds: float) -> int:
    """An MCAP recording cut off by a crash after ``seconds`` of 200 Hz torque messages; returns how many."""
    recorder = Recorder(path, 0, {"x": "1"})
    n = round(seconds / 0.005)
    for k in range(n):
        recorder.write_json(k * 0.005, [("/torque", b'{"t": %f, "torque_Nm": 1.0}' % (k * 0.005))])
    recorder._file.close()  # no index: as a kill -9 leaves it
    with open(path, "ab") as f:
        f.write(b"\x05torn")
    return n


def test_recover_in_place_indexes_the_complete_chunks_without_a_copy(tmp_path: Path) -> None:
    path = tmp_path / "a.mcap"
    n = _unfinished(path, 3.0)
    result = recover_in_place(path)
    assert result.recovered and result.lost_bytes > 0
    kept = [m["t"] for _, _, m in read_messages(path, ["/torque"])]
    assert result.messages == len(kept) and n - 100 <= len(kept) < n  # all but the open chunk
    assert kept == sorted(kept) and kept[0] == 0.0
    assert not recover(path).recovered  # finished: left as it is
    assert [p.name for p in tmp_path.iterdir()] == ["a.mcap"]  # no copy was made


def test_recover_in_place_cuts_chunks_off_until_the_index_fits(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "a.mcap"
    _unfinished(path, 3.0)
    # a disk with this much room left after the file's last complete chunk: more than the index needs (its schemas,
    # about 22 kB since /estimation_state and the gait state's descriptions), less than it and the last chunks
    room = {"bytes": 26_000}

    class _Disk(io.BufferedRandom):
        def truncate(self, size: int | None = None) -> int:
            self.flush()
            room["bytes"] += max(0, os.fstat(self.fileno()).st_size - (size if size is not None else self.tell()))
            return super().truncate(size)

        def write(self, data: Any, /) -> int:
            if len(data) > room["bytes"]:
                raise OSError(errno.ENOSPC, "No space left on device")
            room["bytes"] -= len(data)
            return super().write(data)

    def fake_open(p: Path, mode: str) -> IO[bytes]:
        return _Disk(io.FileIO(p, "r+")) if mode == "r+b" else open(p, mode)

    monkeypatch.setattr("gaitscope.sessions.formats.mcap_io.open", fake_open, raising=False)
    result = recover_in_place(path)
    monkeypatch.undo()
    kept = sum(1 for _ in read_messages(path, ["/torque"]))
    assert result.recovered and result.messages == kept and 0 < kept < 500  # chunks given up for the index

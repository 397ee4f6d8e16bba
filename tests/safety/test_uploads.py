"""Uploads (``server/routes/uploads.py``, ``sessions/imports.py``) against the real app and a real SQLite file.

What is checked: the format is decided by the file's name and content; every bad file is refused with
422 and a reason that names the user's file and no server path; nothing is stored by a refused or
failed upload and nothing stored before is lost; the rows and the recording of an import appear
together; one chunk at a time per upload; quotas on open uploads and disk space; file names without
control characters; the import runs in a worker process and streams (memory does not grow with the
file).
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import hashlib
import io
import json
import math
import shutil
import tracemalloc
from collections.abc import AsyncIterator, Callable, Iterator
from pathlib import Path
from typing import Any

import httpx2
import numpy as np
import pandas as pd
import pytest
from fastapi.testclient import TestClient
from mcap.writer import Writer

from gaitscope.server.app import create_app
from gaitscope.server.settings import Settings
from gaitscope.sessions import schema
from gaitscope.sessions.formats.locohub import write_table
from gaitscope.sessions.formats.mcap_io import read_messages
from gaitscope.sessions.formats.models import default_model_path, load_model
from gaitscope.sessions.live.sources import frames_from_table
from gaitscope.sessions.synth.cohort import CohortSpec, generate_cohort
from gaitscope.sessions.synth.trials import replay_columns, sensor_trial
from tests.waiting import wait_until
from tests.walks import replay_csv

SUBJECT: dict[str, Any] = {"code": "P01", "leg_length_m": 0.9, "mass_kg": 70.0}

# --- helpers -------------------------------------------------------------------------------------


def _settings(tmp_path: Path, **overrides: Any) -> Settings:
    """The test settings (as the ``client`` fixture's) plus ``overrides``."""
    return Settings(
        data_dir=tmp_path / "data", demo=False, leg_view=False, max_upload_mb=5, upload_chunk_kb=64,
        allowed_hosts=["testserver"], **overrides,
    )  # fmt: skip


@pytest.fixture
def make_client(tmp_path: Path) -> Iterator[Callable[..., TestClient]]:
    """Start the app (lifespan included) with the test settings plus ``overrides``."""
    with contextlib.ExitStack() as stack:

        def make(**overrides: Any) -> TestClient:
            return stack.enter_context(TestClient(create_app(_settings(tmp_path, **overrides))))

        yield make


def _subject(client: TestClient) -> int:
    r = client.post("/api/subjects", json=SUBJECT)
    assert r.status_code == 201, r.text
    return int(r.json()["id"])


def _upload(client: TestClient, data: bytes, name: str, subject_id: int) -> tuple[int, Any]:
    """Create, send in chunks, finish: (status, body) of the first refusal or of the finish."""
    r = client.post("/api/uploads", json={"filename": name, "size": len(data), "subject_id": subject_id})
    if r.status_code != 201:
        return r.status_code, r.json()
    up = r.json()
    for off in range(0, len(data), up["chunk_size"]):
        r = client.put(f"/api/uploads/{up['id']}?offset={off}", content=data[off : off + up["chunk_size"]])
        assert r.status_code == 200, r.text
    r = client.post(f"/api/uploads/{up['id']}/finish")
    return r.status_code, r.json()


def _files(root: Path) -> dict[str, str]:
    """Every file under ``root`` but the database, with its sha256."""
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file() and not p.name.startswith("gaitscope.db")
    }


@functools.cache
def _frames() -> list[dict[str, Any]]:
    """About 10 s of simulated sensor frames (100 Hz) as JSON-ready dicts."""
    sensors, _, _ = sensor_trial([(1.0, 0.0, 8)])
    return [f.model_dump(exclude_none=True) for f in frames_from_table(replay_columns(sensors))]


def _mcap(frames: list[dict[str, Any]], topic: str = "/sensor", states: list[dict[str, Any]] | None = None) -> bytes:
    """A finished MCAP with ``frames`` as JSON on ``topic`` (written with ``json.dumps``, so a float NaN
    becomes the token ``NaN``), 5 ms apart, and ``states`` on ``/gait_state``."""
    buf = io.BytesIO()
    writer = Writer(buf)
    writer.start(profile="", library="test")
    channel = writer.register_channel(topic=topic, message_encoding="json", schema_id=0)
    for i, frame in enumerate(frames):
        writer.add_message(channel, log_time=i * 5_000_000, data=json.dumps(frame).encode(), publish_time=0)
    if states is not None:
        gait = writer.register_channel(topic="/gait_state", message_encoding="json", schema_id=0)
        for i, state in enumerate(states):
            writer.add_message(gait, log_time=i * 5_000_000, data=json.dumps(state).encode(), publish_time=0)
    writer.finish()
    return buf.getvalue()


def _edit(frames: list[dict[str, Any]], index: int, **fields: Any) -> list[dict[str, Any]]:
    out = [dict(f) for f in frames]
    out[index].update(fields)
    return out


@functools.cache
def _locohub() -> pd.DataFrame:
    return generate_cohort(
        CohortSpec(n_subjects=1, speeds_m_s=(1.0,), inclines_deg=(0.0, 5.0), strides_per_condition=2)
    )


def _locohub_bytes(suffix: str, tmp_path: Path, frame: pd.DataFrame | None = None) -> bytes:
    path = tmp_path / f"table{suffix}"
    write_table(_locohub() if frame is None else frame, path)
    return path.read_bytes()


def _parquet(frame: pd.DataFrame) -> bytes:
    buf = io.BytesIO()
    frame.to_parquet(buf, index=False)
    return buf.getvalue()


def _recording(tmp_path: Path) -> bytes:
    """A gaitscope recording (``/sensor``, ``/gait_state``, ...) made by importing the replay CSV."""
    from gaitscope.sessions.formats.imports import ImportJob, import_log

    csv_path, target = tmp_path / "walk.csv", tmp_path / "walk.mcap"
    csv_path.write_bytes(replay_csv())
    subject = schema.Subject(id=1, created_utc="2024-01-01T00:00:00+00:00", **SUBJECT)
    import_log(ImportJob(csv_path, "walk.csv", target, subject, load_model(default_model_path())[0]))
    return target.read_bytes()


# --- the format: name and content ----------------------------------------------------------------


@pytest.mark.parametrize("suffix", [".parquet", ".csv"])
def test_locohub_tables_import(make_client: Callable[..., TestClient], tmp_path: Path, suffix: str) -> None:
    client = make_client()
    data = _locohub_bytes(suffix, tmp_path)
    code, trial = _upload(client, data, f"cohort{suffix}", _subject(client))
    assert code == 201, trial
    # one frame per distinct time of each (subject, task)
    expected = sum(g["time_s"].nunique() for _, g in _locohub().groupby(["subject", "task_id"]))
    assert (trial["status"], trial["name"], trial["samples"]) == ("uploaded", f"cohort{suffix}", expected)
    series = client.get(f"/api/trials/{trial['id']}/series?max_points=20000").json()
    assert len(series["t"]) == expected
    session = client.get(f"/api/sessions/{trial['session_id']}").json()
    source = {"kind": "upload", "filename": f"cohort{suffix}", "sha256": hashlib.sha256(data).hexdigest()}
    assert session["state"] == "stopped" and session["source"] == source
    # every signal a channel carries is read (issue #25): both legs' segments and joints, the feet's forces,
    # the centre of mass; what no channel carries is listed as not read
    report = trial["report"]
    assert {
        "thigh_angle_deg", "knee_angle_deg", "hip_angle_contra_deg", "foot_force_N", "com_forward_m", "com_up_vel_m_s"
    } <= set(report["channels"])  # fmt: skip
    assert {schema.ANKLE_MOMENT, schema.PELVIS_ANGLE, schema.TOE_OFF, schema.SPEED} <= set(report["ignored"])
    ran = {e["name"] for e in report["estimators"] if e["ran"]}
    assert {"phase_ekf", "fp_avg", "fp_gf"} <= ran and "com_kin" not in ran  # the table has the centre of mass
    path = client.app.state.ctx.settings.data_dir / trial["path"]  # type: ignore[attr-defined]
    frames = [m for _, _, m in read_messages(path, ["/sensor"])]
    table = _locohub().drop_duplicates(["subject", "task_id", "time_s"])
    for column, channel, scale in ((schema.COM_STANCE_POSITION[1], "com_lateral_m", -1.0),
                                   (schema.KNEE_ANGLE, "knee_angle_deg", 180.0 / math.pi)):  # fmt: skip
        recorded = sorted(f[channel] for f in frames)
        np.testing.assert_allclose(recorded, sorted(scale * table[column].to_numpy()), rtol=1e-12, atol=1e-12)


def test_replay_csv_and_mcap_import(make_client: Callable[..., TestClient], tmp_path: Path) -> None:
    client = make_client()
    sid = _subject(client)
    code, raw = _upload(client, _mcap(_frames()), "raw.mcap", sid)  # sensor frames only: estimated
    assert code == 201 and raw["samples"] == len(_frames()), raw
    code, csv_trial = _upload(client, replay_csv(), "walk.csv", sid)
    assert code == 201 and csv_trial["samples"] == len(_frames()), csv_trial
    recording = _recording(tmp_path)
    code, kept = _upload(client, recording, "recorded.mcap", sid)  # has gait states: kept as recorded
    assert code == 201 and kept["samples"] == len(_frames()), kept
    stored = client.get(f"/api/trials/{kept['id']}/download").content
    assert stored == recording
    assert [t["name"] for t in client.get("/api/trials").json()] == ["raw.mcap", "walk.csv", "recorded.mcap"]


def test_upload_csv_then_review(client: TestClient, tmp_path: Path) -> None:
    sensors, _, _ = sensor_trial([(1.0, 5.0, 30)])
    data = replay_columns(sensors).to_csv(index=False, float_format="%.5f").encode()
    assert len(data) > 3 * 64 * 1024  # several chunks
    code, trial = _upload(client, data, "walk.csv", _subject(client))
    assert code == 201, trial
    assert trial["status"] == "uploaded" and trial["samples"] == len(sensors)
    series = client.get(f"/api/trials/{trial['id']}/series?max_points=20000").json()
    assert len(series["t"]) == len(sensors)
    late = [r for t, r in zip(series["t"], series["incline_deg"], strict=True) if t > series["t"][-1] - 3]
    assert abs(sum(late) / len(late) - 5.0) < 3.0


@pytest.mark.parametrize("source", ["walk.csv", "raw.mcap", "cohort.parquet"])
def test_an_imported_trial_reruns_as_recorded(
    make_client: Callable[..., TestClient], tmp_path: Path, source: str
) -> None:
    """The recording keeps session time on /sensor and the sample period the import estimated with,
    so a review re-run reproduces the imported states."""
    client = make_client()
    content = {"walk.csv": replay_csv(), "raw.mcap": _mcap(_frames())}.get(source) or _locohub_bytes(
        ".parquet", tmp_path
    )
    code, trial = _upload(client, content, source, _subject(client))
    assert code == 201, trial
    recorded = client.get(f"/api/trials/{trial['id']}/series?max_points=20000").json()
    rerun = client.post(f"/api/trials/{trial['id']}/rerun?max_points=20000").json()
    assert rerun["t"] == recorded["t"] and rerun["t"][0] == 0.0
    assert rerun["phase"] == pytest.approx(recorded["phase"], abs=1e-9)
    assert rerun["torque_Nm"] == pytest.approx(recorded["torque_Nm"], abs=1e-9)


# --- bad files: 422 in the user's terms, nothing stored ------------------------------------------

_GOOD_STATES = [
    {"seq": i, "t": i * 0.005, "phase": 0.1, "phase_rate": 1.0, "stride_length_m": 1.2, "incline_deg": 0.0,
     "torque_Nm": 0.0, "tbe_phase": 0.1, "heel_strike": False, "backup_reset": False, "foot_angle_deg": None,
     "shank_angle_deg": None, "thigh_angle_deg": None, "foot_pred_deg": 0.0, "shank_pred_deg": 0.0, "recv_ns": 0}
    for i in range(3)
]  # fmt: skip

#: (name, content builder, words the reason must hold)
BAD_FILES: list[tuple[str, Callable[[Path], bytes], str]] = [
    ("blank.csv", lambda _: b"\n\n", "the file is empty"),
    ("bom.csv", lambda _: b"\xef\xbb\xbf", "the file is empty"),
    ("cut.mcap", lambda _: _mcap(_frames())[: len(_mcap(_frames())) // 2], "the MCAP file is incomplete"),
    ("text.mcap", lambda _: b"time_s,foot_angle_deg\n0,1\n", "not an MCAP file: the content is CSV text"),
    ("magic.mcap", lambda _: b"\x89MCAP9\r\n" + bytes(64), "not an MCAP file: the content is binary data"),
    ("table.mcap", lambda _: _parquet(pd.DataFrame({"x": [1.0]})), "not an MCAP file: the content is a parquet file"),
    ("wrong.csv", lambda _: b"a,b\n1,2\n3,4\n", "neither time_s and a column named as a gaitscope channel"),
    ("garbage.csv", lambda _: bytes(range(256)) * 16, "not a CSV file: the content is binary data"),
    ("recording.csv", lambda _: _mcap(_frames()), "not a CSV file: the content is an MCAP file"),
    ("table.csv", lambda _: _parquet(pd.DataFrame({"x": [1.0]})), "not a CSV file: the content is a parquet file"),
    ("text.parquet", lambda _: b"time_s,foot_angle_deg\n0,1\n", "not a parquet file: the content is CSV text"),
    ("other.parquet", lambda _: _parquet(pd.DataFrame({"x": [1.0, 2.0]})), "missing required column(s)"),
    ("cut.parquet", lambda p: _locohub_bytes(".parquet", p)[:2000], "not a readable parquet file"),
    # another tool's recording whose fields no channel is named as: it needs a mapping (its frames on another
    # topic, named as channels, import: the suggested mapping maps them, tests/server/test_import_preview.py)
    (
        "nosensor.mcap",
        lambda _: _mcap([{"speed": 1.0 + i, "mode": 2} for i in range(20)], topic="/other"),
        "none of its fields is named as a gaitscope channel",
    ),
    ("one.mcap", lambda _: _mcap(_frames()[:1]), "fewer than 2 sensor frames"),
    ("nan_t.mcap", lambda _: _mcap(_edit(_frames(), 5, t=math.nan)), "/sensor message 6: t is NaN"),
    ("inf_t.mcap", lambda _: _mcap(_edit(_frames(), 5, t=math.inf)), "/sensor message 6: t is infinite"),
    ("huge_t.mcap", lambda _: _mcap(_edit(_frames(), 5, t=1e300)), "/sensor message 6: t = 1e+300 s is out of range"),
    ("back_t.mcap", lambda _: _mcap(_edit(_frames(), 5, t=0.0)), "/sensor message 6: time goes backwards"),
    ("same_t.mcap", lambda _: _mcap(_edit(_frames(), 5, t=_frames()[4]["t"])), "/sensor message 6: time repeats"),
    ("long.mcap", lambda _: _mcap([*_frames()[:3], {"seq": 3, "t": 5e6}]), "the log spans 5e+06 s"),
    ("nan_value.mcap", lambda _: _mcap(_edit(_frames(), 5, foot_angle_deg=math.nan)), "foot_angle_deg is NaN"),
    ("inf_value.mcap", lambda _: _mcap(_edit(_frames(), 5, shank_vel_dps=-math.inf)), "shank_vel_dps is infinite"),
    ("text_value.mcap", lambda _: _mcap(_edit(_frames(), 5, heel_up_m="high")), "/sensor message 6: heel_up_m"),
    ("nan_state.mcap", lambda _: _mcap(_frames(), states=[*_GOOD_STATES[:2], {**_GOOD_STATES[2], "phase": math.nan}]),
     "/gait_state message 3: phase is NaN"),
    ("huge_state.mcap", lambda _: _mcap(_frames(), states=[*_GOOD_STATES[:2], {**_GOOD_STATES[2], "t": 1e300}]),
     "/gait_state message 3: t = 1e+300 s is out of range"),
    ("nan.csv", lambda _: b"time_s,foot_angle_deg\n0,1\n0.01,nan\n", "column 'foot_angle_deg', row 3: NaN"),
    ("huge_t.csv", lambda _: b"time_s,foot_angle_deg\n0,1\n1e300,2\n", "'time_s', row 3: t = 1e+300 s is out of range"),
    ("back_t.csv", lambda _: b"time_s,foot_angle_deg\n0,1\n0.02,2\n0.01,3\n", "row 4: time goes backwards"),
    ("short.csv", lambda _: b"time_s,foot_angle_deg\n0,1\n", "need at least 2 data rows"),
]  # fmt: skip


@pytest.mark.parametrize(("name", "content", "reason"), BAD_FILES, ids=[b[0] for b in BAD_FILES])
def test_bad_files_are_refused_in_the_users_terms(
    make_client: Callable[..., TestClient], tmp_path: Path, name: str, content: Callable[[Path], bytes], reason: str
) -> None:
    client = make_client()
    sid = _subject(client)
    code, good = _upload(client, replay_csv(), "kept.csv", sid)
    assert code == 201
    data_dir = tmp_path / "data"
    before = _files(data_dir)
    code, body = _upload(client, content(tmp_path), name, sid)
    assert code == 422, body
    detail = body["detail"]
    assert detail.startswith(f"file {name}") and reason in detail, detail
    assert str(tmp_path) not in detail and ".part" not in detail and "uploads/" not in detail
    assert _files(data_dir) == before  # nothing stored, nothing lost
    assert [t["id"] for t in client.get("/api/trials").json()] == [good["id"]]
    assert len(client.get("/api/sessions").json()) == 1
    assert len(client.get(f"/api/trials/{good['id']}/series?max_points=20000").json()["t"]) == len(_frames())


def test_bad_uploads_store_nothing(client: TestClient, tmp_path: Path) -> None:
    sid = _subject(client)
    data_dir = tmp_path / "data"
    before = _files(data_dir)
    sensors, _, _ = sensor_trial([(1.0, 0.0, 3)])
    frame = replay_columns(sensors).astype({"shank_angle_deg": object})
    frame.loc[40, "shank_angle_deg"] = "n/a"
    code, body = _upload(client, frame.to_csv(index=False).encode(), "bad.csv", sid)
    assert code == 422 and "column 'shank_angle_deg', row 42" in body["detail"]
    code, body = _upload(client, b"\x89MCAP0\r\n" + b"\x00" * 64, "cut.mcap", sid)
    assert code == 422 and "cut.mcap" in body["detail"]
    code, body = _upload(client, bytes(9 * 1024 * 1024), "big.csv", sid)
    assert code == 413 and "limit is 8 MiB" in body["detail"]
    assert _files(data_dir) == before
    assert client.get("/api/trials").json() == []


def test_upload_protocol_errors(client: TestClient) -> None:
    sid = _subject(client)
    up = client.post("/api/uploads", json={"filename": "a.csv", "size": 10, "subject_id": sid}).json()
    assert client.put(f"/api/uploads/{up['id']}?offset=5", content=b"12345").status_code == 409
    assert client.put(f"/api/uploads/{up['id']}?offset=0", content=b"12345678901").status_code == 413
    assert client.post(f"/api/uploads/{up['id']}/finish").status_code == 409
    assert client.delete(f"/api/uploads/{up['id']}").status_code == 204
    assert client.post(f"/api/uploads/{up['id']}/finish").status_code == 404
    r = client.post("/api/uploads", json={"filename": "../evil.csv", "size": 10, "subject_id": sid})
    assert r.status_code == 422


def test_empty_file_is_refused_at_creation(make_client: Callable[..., TestClient]) -> None:
    client = make_client()
    r = client.post("/api/uploads", json={"filename": "empty.csv", "size": 0, "subject_id": _subject(client)})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "size"]


@pytest.mark.parametrize(
    "name",
    ["nul\x00.csv", "line\nbreak.csv", "tab\t.csv", "bell\x07.mcap", "del\x7f.csv", "c1\x85.csv",
     "rtl\u202egpj.parquet", "isolate\u2066.csv", "sep\u2028.csv"],
)  # fmt: skip
def test_control_characters_in_the_name_are_refused(make_client: Callable[..., TestClient], name: str) -> None:
    client = make_client()
    r = client.post("/api/uploads", json={"filename": name, "size": 10, "subject_id": _subject(client)})
    assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "filename"]


def test_ordinary_names_are_kept(make_client: Callable[..., TestClient]) -> None:
    client = make_client()
    code, trial = _upload(client, replay_csv(), "Gang 2 (Müller) – 5°.csv", _subject(client))
    assert code == 201 and trial["name"] == "Gang 2 (Müller) – 5°.csv"


# --- atomic storage -----------------------------------------------------------------------------


def test_rows_and_recording_are_stored_together(
    make_client: Callable[..., TestClient], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    client = make_client()
    sid = _subject(client)
    store = client.app.state.ctx.store  # type: ignore[attr-defined]
    real = store.create_upload_trial
    moved: list[Path] = []

    def failing_commit(*args: Any, before_commit: Callable[[], None], **kwargs: Any) -> schema.Trial:
        def move_then_fail() -> None:
            before_commit()  # the recording is moved into place ...
            moved.extend((tmp_path / "data" / "recordings").glob("*.mcap"))
            raise OSError(5, "simulated I/O error at commit")  # ... and the commit fails

        return real(*args, before_commit=move_then_fail, **kwargs)

    before = _files(tmp_path / "data")
    monkeypatch.setattr(store, "create_upload_trial", failing_commit)
    with pytest.raises(OSError, match="simulated"):
        _upload(client, replay_csv(), "walk.csv", sid)
    assert len(moved) == 1 and not moved[0].exists()
    assert _files(tmp_path / "data") == before
    assert client.get("/api/trials").json() == [] and client.get("/api/sessions").json() == []
    monkeypatch.undo()
    code, trial = _upload(client, replay_csv(), "walk.csv", sid)
    assert code == 201 and (tmp_path / "data" / trial["path"]).is_file()


def test_store_creates_upload_session_and_trial_in_one_transaction(make_client: Callable[..., TestClient]) -> None:
    client = make_client()
    sid = _subject(client)
    store = client.app.state.ctx.store  # type: ignore[attr-defined]

    def fail() -> None:
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError, match="No space"):
        store.create_upload_trial(sid, "a.csv", "recordings/a.mcap", 10, 0.5, before_commit=fail)
    assert store.list_sessions() == [] and store.list_trials() == []
    trial = store.create_upload_trial(sid, "a.csv", "recordings/a.mcap", 10, 0.5)
    assert (trial.name, trial.path, trial.status, trial.samples, trial.duration_s) == (
        "a.csv", "recordings/a.mcap", "uploaded", 10, 0.5,
    )  # fmt: skip
    session = store.get_session(trial.session_id)
    assert session.state == "stopped" and session.source == schema.UploadSource(filename="a.csv")
    assert session.stopped_utc is not None and trial.stopped_utc is not None


# --- one chunk at a time -------------------------------------------------------------------------


async def _blocked_body(
    first: bytes, rest: bytes, started: asyncio.Event, release: asyncio.Event
) -> AsyncIterator[bytes]:
    yield first
    started.set()
    await release.wait()
    yield rest


def test_concurrent_chunks_at_one_offset(make_client: Callable[..., TestClient], tmp_path: Path) -> None:
    client = make_client()
    data = b"time_s,foot_angle_deg\n0,1\n0.01,2\n"
    up = client.post(
        "/api/uploads", json={"filename": "a.csv", "size": len(data), "subject_id": _subject(client)}
    ).json()
    url = f"http://testserver/api/uploads/{up['id']}"

    async def race() -> tuple[int, int, int, bool]:
        started, release = asyncio.Event(), asyncio.Event()
        async with httpx2.AsyncClient(transport=httpx2.ASGITransport(app=client.app)) as http:
            first = asyncio.create_task(
                http.put(f"{url}?offset=0", content=_blocked_body(data[:5], data[5:], started, release))
            )
            await started.wait()
            second = await http.put(f"{url}?offset=0", content=data)
            finish = await http.post(f"{url}/finish")
            release.set()
            return (await first).status_code, second.status_code, finish.status_code, "being received" in finish.text

    assert asyncio.run(race()) == (200, 409, 409, True)
    assert (tmp_path / "data" / "uploads" / f"{up['id']}.part").read_bytes() == data  # written once
    assert client.post(f"/api/uploads/{up['id']}/finish").status_code == 201


def test_cancel_during_a_chunk(make_client: Callable[..., TestClient], tmp_path: Path) -> None:
    client = make_client()
    data = b"time_s,foot_angle_deg\n0,1\n0.01,2\n"
    up = client.post(
        "/api/uploads", json={"filename": "a.csv", "size": len(data), "subject_id": _subject(client)}
    ).json()
    url = f"http://testserver/api/uploads/{up['id']}"

    async def race() -> tuple[int, int]:
        started, release = asyncio.Event(), asyncio.Event()
        async with httpx2.AsyncClient(transport=httpx2.ASGITransport(app=client.app)) as http:
            put = asyncio.create_task(
                http.put(f"{url}?offset=0", content=_blocked_body(data[:5], data[5:], started, release))
            )
            await started.wait()
            cancel = await http.delete(url)
            release.set()
            return cancel.status_code, (await put).status_code

    assert asyncio.run(race()) == (204, 404)
    assert list((tmp_path / "data" / "uploads").iterdir()) == []


# --- quotas --------------------------------------------------------------------------------------


def test_open_uploads_are_limited(make_client: Callable[..., TestClient]) -> None:
    client = make_client(max_open_uploads=2)
    body = {"filename": "a.csv", "size": 10, "subject_id": _subject(client)}
    first, second = (client.post("/api/uploads", json=body).json() for _ in range(2))
    r = client.post("/api/uploads", json=body)
    assert r.status_code == 429 and "2 uploads are open" in r.json()["detail"]
    assert client.delete(f"/api/uploads/{first['id']}").status_code == 204
    assert client.post("/api/uploads", json=body).status_code == 201
    assert client.put(f"/api/uploads/{second['id']}?offset=0", content=b"0123456789").status_code == 200


def test_idle_uploads_expire(make_client: Callable[..., TestClient], tmp_path: Path) -> None:
    client = make_client(max_open_uploads=1, upload_idle_s=0.05)
    body = {"filename": "a.csv", "size": 10, "subject_id": _subject(client)}
    stale = client.post("/api/uploads", json=body).json()
    # refused (one open at most) until the stale one has been idle 0.05 s and expires
    fresh = wait_until(lambda: (r := client.post("/api/uploads", json=body)).status_code == 201 and r, 10.0, "expiry")
    assert client.put(f"/api/uploads/{stale['id']}?offset=0", content=b"0123456789").status_code == 404
    assert [p.name for p in (tmp_path / "data" / "uploads").iterdir()] == [f"{fresh.json()['id']}.part"]


def test_disk_space_is_checked(make_client: Callable[..., TestClient], monkeypatch: pytest.MonkeyPatch) -> None:
    client = make_client(upload_min_free_mb=100)
    sid = _subject(client)
    real = shutil.disk_usage
    free = 100 * 2**20 + 3 * 2**20  # 3 MiB above the margin

    def usage(path: Any) -> Any:
        return real(path)._replace(free=free)

    monkeypatch.setattr(shutil, "disk_usage", usage)
    r = client.post("/api/uploads", json={"filename": "a.csv", "size": 2 * 2**20, "subject_id": sid})
    assert r.status_code == 201
    r = client.post("/api/uploads", json={"filename": "b.csv", "size": 2 * 2**20, "subject_id": sid})
    assert r.status_code == 507 and r.json()["detail"].startswith("not enough free disk space on the server for b.csv")
    assert (
        client.post("/api/uploads", json={"filename": "c.csv", "size": 2**20 - 1, "subject_id": sid}).status_code == 201
    )


def test_a_restart_clears_what_uploads_left(tmp_path: Path) -> None:
    uploads = tmp_path / "data" / "uploads"
    uploads.mkdir(parents=True)
    for name in ("abc.part", "abc.import.mcap", "abc.part.link.csv"):  # a chunk, an import's recording, a link
        (uploads / name).write_bytes(b"x")
    with TestClient(create_app(_settings(tmp_path))):
        assert list(uploads.iterdir()) == []


# --- the worker process and memory ---------------------------------------------------------------


def test_imports_run_in_a_worker_process(tmp_path: Path) -> None:
    with TestClient(create_app(_settings(tmp_path))) as client:
        uploads = client.app.state.ctx.uploads  # type: ignore[attr-defined]
        assert not uploads.worker_started  # created lazily
        code, _ = _upload(client, replay_csv(), "walk.csv", _subject(client))
        assert code == 201 and uploads.worker_started and uploads.start_method in ("forkserver", "spawn")
    assert not uploads.worker_started  # the lifespan shut it down


def _synthetic_csv(path: Path, rows: int) -> int:
    t = np.arange(rows) * 0.01
    amplitude = {name: 0.2 if name.endswith("_m") else 20.0 for name in schema.REPLAY_SIGNALS}  # metres, degrees
    signals = {n: amplitude[n] * np.sin(2 * np.pi * t + k) for k, n in enumerate(schema.REPLAY_SIGNALS)}
    columns = {"time_s": t, **signals}
    pd.DataFrame(columns).to_csv(path, index=False, float_format="%.6f")
    return path.stat().st_size


@pytest.mark.slow
def test_import_memory_does_not_grow_with_the_file(tmp_path: Path) -> None:
    from gaitscope.sessions.formats.imports import ImportJob, import_log

    subject = schema.Subject(id=1, created_utc="2024-01-01T00:00:00+00:00", **SUBJECT)
    model = load_model(default_model_path())[0]

    def peak(rows: int) -> tuple[int, int, int]:
        source, target = tmp_path / f"walk{rows}.csv", tmp_path / f"walk{rows}.mcap"
        size = _synthetic_csv(source, rows)
        tracemalloc.start()
        try:
            result = import_log(ImportJob(source, "walk.csv", target, subject, model))
            return tracemalloc.get_traced_memory()[1], size, result.samples
        finally:
            tracemalloc.stop()

    peak(300)  # warm up: one-time allocations (schemas, caches)
    small, small_size, small_samples = peak(2_000)  # several batches (BATCH_FRAMES) already
    large, large_size, large_samples = peak(8_000)
    assert (small_samples, large_samples) == (2_000, 8_000)
    assert large_size - small_size > 400_000
    # the old import held every row as text, frame and state: about 26 bytes per byte of the file
    assert large - small < (large_size - small_size) / 4, (small, large, small_size, large_size)
    assert sum(1 for _ in read_messages(tmp_path / "walk8000.mcap", ["/gait_state"])) == 8_000

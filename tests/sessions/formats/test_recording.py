"""Trial MCAP files: recording, reading, checking and crash recovery, on real files in tmp_path."""

from __future__ import annotations

import errno
import io
import itertools
import json
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import textwrap
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace

import pytest
from mcap.reader import make_reader
from mcap.records import Chunk, Message
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.writer import Writer
from pydantic import BaseModel

from gaitscope.sessions import schema
from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.formats import mcap_io, recording
from gaitscope.sessions.formats.mcap_io import (
    check_mcap,
    decimate,
    read_events,
    read_messages,
    read_sensor_frames,
    read_series,
    recover,
)
from gaitscope.sessions.formats.recording import FLUSH_INTERVAL_S, Recorder, RecordingError

START_NS = 1_700_000_000_123_456_789
RATE_HZ = 200.0
STRIKE_EVERY = 100  # samples between heel strikes
META = {"subject": "S01", "session_id": "3", "trial": "walk-1"}


def frame(i: int) -> schema.SensorFrame:
    t = i / RATE_HZ
    return schema.SensorFrame(
        seq=i,
        t=t,
        foot_angle_deg=20 * math.sin(2 * math.pi * t),
        foot_vel_dps=1 / (i + 3),
        shank_angle_deg=-5.0 + i * 1e-3,
        shank_vel_dps=None if i % 7 == 0 else 0.1 * i,
        heel_forward_m=0.25,
        heel_up_m=0.01 * (i % 5),
        thigh_angle_deg=None,
        heel_strike=i % STRIKE_EVERY == 7,
        sent_ns=START_NS + 5_000_000 * i,
    )


def state(i: int, torque: float | None = None) -> schema.GaitState:
    t = i / RATE_HZ
    return schema.GaitState(
        seq=i,
        t=t,
        phase=(i % STRIKE_EVERY) / STRIKE_EVERY,
        phase_rate=1 / (i + 1),
        stride_length_m=1.2 + 1e-4 * i,
        incline_deg=-2.5,
        torque_Nm=math.sin(i / 10) if torque is None else torque,
        tbe_phase=0.5,
        heel_strike=i % STRIKE_EVERY == 7,
        backup_reset=False,
        foot_angle_deg=20 * math.sin(2 * math.pi * t),
        shank_angle_deg=-5.0,
        thigh_angle_deg=None,
        foot_pred_deg=0.3,
        shank_pred_deg=-0.3,
        sent_ns=None if i % 2 else START_NS + i,
        recv_ns=START_NS + 5_000_000 * i + 1234,
    )


def torque(i: int) -> schema.TorqueCommand:
    return schema.TorqueCommand(seq=i, t=i / RATE_HZ, torque_Nm=0.5 * i)


def write_samples(rec: Recorder, start: int, stop: int) -> None:
    for i in range(start, stop):
        rec.write("/sensor", i / RATE_HZ, frame(i))
        rec.write("/gait_state", i / RATE_HZ, state(i))
        rec.write("/torque", i / RATE_HZ, torque(i))


def record_spans(path: Path) -> list[tuple[str, int, int, int]]:
    """(record type, start offset, end offset, messages inside) of every record, in file order."""
    out = []
    with path.open("rb") as f:
        start = len(mcap_io._MAGIC)
        for record in StreamReader(f, emit_chunks=True).records:
            inner = breakup_chunk(record) if isinstance(record, Chunk) else []
            n = sum(isinstance(r, Message) for r in inner)
            out.append((type(record).__name__, start, f.tell(), n))
            start = f.tell()
    return out


def chunk_message_counts(path: Path) -> list[tuple[int, int, int]]:
    """(start offset, end offset, messages) of every chunk in the file, in file order."""
    return [(start, end, n) for kind, start, end, n in record_spans(path) if kind == "Chunk"]


# --- recording and reading back ------------------------------------------------------------------


EVENTS = [
    schema.Event(
        id=1,
        session_id=3,
        t=0.5,
        wall_utc="2024-05-01T10:00:00.5Z",
        kind="setting",
        text="torque gain 1.0 -> 1.5",
        field="torque_gain",
        before=1.0,
        after=1.5,
        actor="clinician",
    ),
    schema.Event(
        id=2,
        session_id=3,
        t=1.25,
        wall_utc="2024-05-01T10:00:01.25Z",
        kind="setting",
        text="model",
        field="model",
        before="default",
        after="7",
        actor="clinician",
    ),
    schema.Event(id=3, session_id=3, t=2.0, wall_utc="2024-05-01T10:00:02Z", kind="annotation", text="trip"),
]


@pytest.fixture
def recorded(tmp_path: Path) -> Path:
    """600 samples (3 s at 200 Hz) on every channel, two settings messages and three events."""
    path = tmp_path / "recordings" / "trial.mcap"
    with Recorder(path, START_NS, META) as rec:
        rec.write("/settings", 0.0, schema.SessionSettings())
        write_samples(rec, 0, 300)
        rec.write("/settings", 1.5, schema.SessionSettings(torque_gain=1.5, model="m2"))
        write_samples(rec, 300, 600)
        for event in EVENTS:
            rec.write_event(event)
        assert rec.samples == 600
        assert rec.duration_s == pytest.approx(599 / RATE_HZ, abs=1e-12)
    return path


def test_round_trip_values(recorded: Path) -> None:
    check_mcap(recorded)
    assert read_sensor_frames(recorded) == [frame(i) for i in range(600)]
    states = [schema.GaitState.model_validate(m) for _, _, m in read_messages(recorded, ["/gait_state"])]
    assert states == [state(i) for i in range(600)]
    torques = [schema.TorqueCommand.model_validate(m) for _, _, m in read_messages(recorded, ["/torque"])]
    assert torques == [torque(i) for i in range(600)]
    settings = [m for _, _, m in read_messages(recorded, ["/settings"])]
    assert settings == [
        schema.SessionSettings().model_dump(),
        {**settings[0], "torque_gain": 1.5, "model": "m2"},
    ]
    assert [schema.Event.model_validate(e) for e in read_events(recorded)] == EVENTS
    assert read_events(recorded)[1]["before"] == "default"  # a str setting stays str
    assert read_events(recorded)[2].keys() == {"log_time_ns", *EVENTS[2].model_dump(exclude_none=True)}


def test_log_times_are_start_plus_t(recorded: Path) -> None:
    messages = list(read_messages(recorded))
    assert len(messages) == 3 * 600 + 2 + 3
    assert [lt for _, lt, _ in messages] == sorted(lt for _, lt, _ in messages)
    for topic, log_time, msg in messages:
        if topic != "/events" and topic != "/settings":
            assert log_time == START_NS + round(msg["t"] * 1e9)
    events = [(lt, m) for topic, lt, m in messages if topic == "/events"]
    for (log_time, msg), event in zip(events, EVENTS, strict=True):
        assert log_time == START_NS + round(event.t * 1e9)
        stamp = {"sec": log_time // 1_000_000_000, "nsec": log_time % 1_000_000_000}
        assert msg["start_time"] == msg["end_time"] == stamp
    assert [lt for topic, lt, _ in messages if topic == "/settings"] == [START_NS, START_NS + 1_500_000_000]
    with recorded.open("rb") as f:
        for _, _, message in make_reader(f).iter_messages():
            assert message.publish_time == message.log_time


def test_summary_names_encodings_and_metadata(recorded: Path) -> None:
    with recorded.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        channels = {
            c.topic: (
                summary.schemas[c.schema_id].name,
                summary.schemas[c.schema_id].encoding,
                c.message_encoding,
            )
            for c in summary.channels.values()
        }
        assert channels == {
            "/sensor": ("gaitscope.SensorFrame", "jsonschema", "json"),
            "/gait_state": ("gaitscope.GaitState", "jsonschema", "json"),
            "/torque": ("gaitscope.TorqueCommand", "jsonschema", "json"),
            "/settings": ("gaitscope.SessionSettings", "jsonschema", "json"),
            "/events": ("foxglove.Event", "jsonschema", "json"),
            "/imu_calibration": ("gaitscope.ImuCalibration", "jsonschema", "json"),
            "/gp_models": ("gaitscope.GPModelRecord", "jsonschema", "json"),
            "/estimation_state": ("gaitscope.EstimationState", "jsonschema", "json"),
        }
        models: dict[str, type[BaseModel]] = {
            "/sensor": schema.SensorFrame,
            "/gait_state": schema.GaitState,
            "/torque": schema.TorqueCommand,
            "/settings": schema.SessionSettings,
            "/events": schema.FoxgloveEvent,
            "/imu_calibration": schema.ImuCalibration,
            "/gp_models": schema.GPModelRecord,
            "/estimation_state": schema.EstimationState,
        }
        for c in summary.channels.values():
            assert summary.schemas[c.schema_id].data == json.dumps(models[c.topic].model_json_schema()).encode()
        counts = {summary.channels[i].topic: n for i, n in summary.statistics.channel_message_counts.items()}
        assert counts == {"/sensor": 600, "/gait_state": 600, "/torque": 600, "/settings": 2, "/events": 3}
        assert reader.get_header().library == "gaitscope"
        [meta] = list(reader.iter_metadata())
        assert meta.name == "gaitscope"
        assert meta.metadata == {**META, "start_ns": str(START_NS)}
        # A chunk closes once it spans FLUSH_INTERVAL_S (0.5 s) of session time: what kill -9 can lose.
        # The last one also holds the three events, written after the samples at earlier times.
        spans = [(c.message_end_time - c.message_start_time) / 1e9 for c in summary.chunk_indexes]
        assert spans[:-1] == [FLUSH_INTERVAL_S] * 5
        assert spans[-1] == pytest.approx(2.995 - 0.5)


def test_recorder_refuses_misuse(tmp_path: Path) -> None:
    path = tmp_path / "t.mcap"
    rec = Recorder(path, START_NS, {})
    with pytest.raises(ValueError, match="unknown MCAP topic '/imu'"):
        rec.write("/imu", 0.0, frame(0))
    with pytest.raises(TypeError, match="/sensor carries SensorFrame, not GaitState"):
        rec.write("/sensor", 0.0, state(0))
    rec.write("/sensor", 0.0, frame(0))
    rec.finish()
    rec.finish()  # idempotent
    with pytest.raises(ValueError, match="finished"):
        rec.write("/sensor", 0.005, frame(1))
    with pytest.raises(FileExistsError):
        Recorder(path, START_NS, {})
    assert rec.samples == 0 and rec.duration_s == 0.0
    assert [m["seq"] for _, _, m in read_messages(path)] == [0]
    with pytest.raises(ValueError, match="flush_interval_s must be above 0, got 0"):
        Recorder(tmp_path / "u.mcap", START_NS, {}, flush_interval_s=0)
    with pytest.raises(ValueError, match="fsync_interval_s must be at least 0, got -1"):
        Recorder(tmp_path / "u.mcap", START_NS, {}, fsync_interval_s=-1)
    assert not (tmp_path / "u.mcap").exists()


def test_context_manager_finishes_on_error(tmp_path: Path) -> None:
    path = tmp_path / "t.mcap"
    with pytest.raises(RuntimeError, match="boom"), Recorder(path, START_NS, {}) as rec:
        write_samples(rec, 0, 10)
        raise RuntimeError("boom")
    check_mcap(path)
    assert len(read_sensor_frames(path)) == 10


# --- read_series ---------------------------------------------------------------------------------


def test_read_series_bounds(recorded: Path) -> None:
    full = read_series(recorded, None, None, 10_000)
    assert list(full) == list(mcap_io.SERIES_COLUMNS) and next(iter(full)) == "t"
    assert set(full) == set(schema.GaitState.model_fields)
    assert full["seq"] == list(range(600))
    assert full["torque_Nm"] == [state(i).torque_Nm for i in range(600)]
    assert full["sent_ns"][:2] == [START_NS, None]
    window = read_series(recorded, 0.5, 1.0, 10_000)
    assert window["seq"] == list(range(100, 201))  # both bounds inclusive
    assert window["t"][0] == 0.5 and window["t"][-1] == 1.0
    assert read_series(recorded, 2.9, None, 10_000)["seq"] == list(range(580, 600))
    assert read_series(recorded, None, 0.01, 10_000)["seq"] == [0, 1, 2]
    assert read_series(recorded, 5.0, 6.0, 10_000) == {c: [] for c in mcap_io.SERIES_COLUMNS}
    with pytest.raises(ValueError, match="max_points"):
        read_series(recorded, None, None, 1)


def test_read_series_seeks_through_the_index(tmp_path: Path) -> None:
    # Wreck the last chunk: a window in the first second must not read it, the whole file must fail.
    recorded = tmp_path / "t.mcap"
    with Recorder(recorded, START_NS, {}) as rec:
        write_samples(rec, 0, 600)
    with recorded.open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    last = summary.chunk_indexes[-1]
    assert last.message_start_time > START_NS + 2_000_000_000
    with recorded.open("r+b") as f:
        f.seek(last.chunk_start_offset + 60)
        f.write(b"\0" * 200)
    assert read_series(recorded, 0.2, 0.4, 10_000)["seq"] == list(range(40, 81))
    with pytest.raises(DataFormatError, match=rf"^file {re.escape(str(recorded))}: damaged MCAP data"):
        read_series(recorded, None, None, 10_000)


def test_decimation_keeps_peaks_and_heel_strikes(tmp_path: Path) -> None:
    path = tmp_path / "peaks.mcap"
    n = 1000
    spikes = {333: 50.0, 444: -20.0, 445: 49.0}
    with Recorder(path, START_NS, {}) as rec:
        for i in range(n):
            rec.write("/gait_state", i / RATE_HZ, state(i, torque=spikes.get(i, 0.0)))
    strikes = [i / RATE_HZ for i in range(n) if i % STRIKE_EVERY == 7]
    series = read_series(path, None, None, 40)
    assert decimate([state(i, torque=spikes.get(i, 0.0)).model_dump() for i in range(n)], 40) == series
    assert all(len(col) == 40 for col in series.values())
    assert json.loads(json.dumps(series)) == series  # plain Python values, ready for a JSON response
    assert max(series["torque_Nm"]) == 50.0 and min(series["torque_Nm"]) == -20.0
    assert series["torque_Nm"].count(49.0) == 1  # 444 and 445 share a bucket: min then max, in order
    i = series["torque_Nm"].index(-20.0)
    assert series["torque_Nm"][i + 1] == 49.0
    assert max(series["foot_angle_deg"]) == pytest.approx(20.0, abs=0.01)
    assert series["thigh_angle_deg"] == [None] * 40
    assert series["t"] == sorted(series["t"]) and series["t"][0] == 0.0 and series["t"][-1] == (n - 1) / RATE_HZ
    hit_times = [t for t, hs in zip(series["t"], series["heel_strike"], strict=True) if hs]
    assert len(hit_times) == len(strikes) == 10
    bucket_s = n / 20 / RATE_HZ
    assert all(abs(a - b) <= bucket_s / 2 for a, b in zip(hit_times, strikes, strict=True))
    window = read_series(path, 1.0, 2.0, 20)  # 201 samples in the window, decimated to 20
    assert len(window["t"]) == 20 and window["t"][0] == 1.0 and window["t"][-1] == 2.0
    assert max(window["torque_Nm"]) == 50.0  # sample 333 is at 1.665 s


# --- checking ------------------------------------------------------------------------------------


def test_non_mcap_files_are_refused(tmp_path: Path) -> None:
    csv = tmp_path / "trial.mcap"
    csv.write_text("time_s,foot_angle_deg\n0.0,1.0\n")
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    for path, reason in ((csv, "not an MCAP file"), (empty, "empty file")):
        for call in (check_mcap, read_sensor_frames, recover, lambda p: list(read_messages(p))):
            with pytest.raises(DataFormatError, match=rf"^file {re.escape(str(path))}: {reason}"):
                call(path)
    assert csv.read_text() == "time_s,foot_angle_deg\n0.0,1.0\n"  # recover left it alone


def test_garbage_after_magic_is_not_finished(tmp_path: Path) -> None:
    path = tmp_path / "garbage.mcap"
    path.write_bytes(mcap_io._MAGIC + bytes(range(256)) * 40)
    with pytest.raises(DataFormatError, match=rf"^file {re.escape(str(path))}: the file was not finished \(no index\)"):
        check_mcap(path)
    with pytest.raises(DataFormatError, match="not finished"):
        read_series(path, None, None, 100)


def test_mcap_without_sensor_channel_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "other.mcap"
    with path.open("wb") as f:
        writer = Writer(f)
        writer.start()
        schema_id = writer.register_schema("x", "jsonschema", b"{}")
        channel = writer.register_channel("/gait_state", "json", schema_id)
        writer.add_message(channel, 1, state(0).model_dump_json().encode(), 1)
        writer.finish()
    with pytest.raises(DataFormatError, match=rf"^file {re.escape(str(path))}: no /sensor channel"):
        check_mcap(path)
    with pytest.raises(DataFormatError, match=r"^file upload\.mcap: no /sensor channel"):
        check_mcap(path, name="upload.mcap")


# --- crash recovery ------------------------------------------------------------------------------


def test_recover_file_copied_before_finish(tmp_path: Path) -> None:
    path, copy = tmp_path / "t.mcap", tmp_path / "crashed.mcap"
    with Recorder(path, START_NS, META) as rec:
        write_samples(rec, 0, 1100)
        shutil.copyfile(path, copy)  # what a crash at this moment would leave on disk
        write_samples(rec, 1100, 1200)
    written_at_copy = 3 * 1100
    cut = copy.stat().st_size
    chunks = chunk_message_counts(path)
    complete = sum(n for _, end, n in chunks if end <= cut)
    per_chunk = max(n for _, _, n in chunks)
    assert complete >= written_at_copy - per_chunk > 0

    with pytest.raises(DataFormatError, match=rf"^file {re.escape(str(copy))}: the file was not finished \(no index\)"):
        check_mcap(copy)
    result = recover(copy)
    assert result == mcap_io.RecoveryResult(messages=complete, lost_bytes=0, recovered=True)
    check_mcap(copy)
    assert read_sensor_frames(copy) == read_sensor_frames(path)[: len(read_sensor_frames(copy))]
    assert len(list(read_messages(copy))) == complete
    with copy.open("rb") as f:
        reader = make_reader(f)
        assert [m.metadata for m in reader.iter_metadata()] == [{**META, "start_ns": str(START_NS)}]
        assert reader.get_header().library == "gaitscope"

    before = copy.read_bytes()
    assert recover(copy) == mcap_io.RecoveryResult(messages=complete, lost_bytes=0, recovered=False)
    assert copy.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["crashed.mcap", "t.mcap"]


@pytest.mark.parametrize("where", ["summary", "mid_last_chunk", "record_header"])
def test_recover_truncated_file(recorded: Path, where: str) -> None:
    with recorded.open("rb") as f:
        summary = make_reader(f).get_summary()
        assert summary is not None and summary.statistics is not None
    total = summary.statistics.message_count
    chunks = chunk_message_counts(recorded)
    last_start, last_end, last_n = chunks[-1]
    [data_end] = [end for kind, _, end, _ in record_spans(recorded) if kind == "DataEnd"]
    cut, expected_messages, expected_lost = {
        "summary": (data_end, total, 0),  # DataEnd complete, summary and footer gone
        "mid_last_chunk": ((last_start + last_end) // 2, total - last_n, (last_end - last_start) // 2),
        "record_header": (last_start + 5, total - last_n, 5),  # opcode and half a length
    }[where]
    with recorded.open("r+b") as f:
        f.truncate(cut)
    result = recover(recorded)
    assert result == mcap_io.RecoveryResult(messages=expected_messages, lost_bytes=expected_lost, recovered=True)
    check_mcap(recorded)
    assert len(list(read_messages(recorded))) == expected_messages


def test_recover_skips_a_damaged_chunk_and_reads_on(tmp_path: Path) -> None:
    path = tmp_path / "t.mcap"
    with Recorder(path, START_NS, {}) as rec:
        write_samples(rec, 0, 800)
    (_, _, n0), (s1, e1, _), *rest = chunk_message_counts(path)
    raw = bytearray(path.read_bytes())
    raw[s1 + 60 : s1 + 260] = b"\0" * 200  # inside chunk 1's compressed data
    cut = rest[0][1]  # unfinished: ends after chunk 2
    path.write_bytes(bytes(raw[:cut]))
    result = recover(path)
    assert result == mcap_io.RecoveryResult(messages=n0 + rest[0][2], lost_bytes=e1 - s1, recovered=True)
    seqs = [m["seq"] for _, _, m in read_messages(path, ["/torque"])]
    assert seqs[0] == 0 and max(b - a for a, b in itertools.pairwise(seqs)) > 100  # chunk 1's gap


def test_recover_failure_leaves_the_original(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "t.mcap"
    with Recorder(path, START_NS, {}) as rec:
        write_samples(rec, 0, 400)
        shutil.copyfile(path, tmp_path / "crashed.mcap")
    crashed = tmp_path / "crashed.mcap"
    before = crashed.read_bytes()

    def disk_full(self: Writer) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(Writer, "finish", disk_full)
    with pytest.raises(OSError, match="No space left"):
        recover(crashed)
    assert crashed.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["crashed.mcap", "t.mcap"]


_CRASHING_RECORDER = textwrap.dedent(
    """
    import sys, time
    from pathlib import Path
    from tests.sessions.formats.test_recording import frame, state, torque
    from gaitscope.sessions.formats.recording import Recorder

    rec = Recorder(Path(sys.argv[1]), time.time_ns(), {"subject": "S01"})
    print("recording", flush=True)
    start = time.perf_counter()
    i = 0
    while True:
        rec.write("/sensor", i / 200, frame(i))
        rec.write("/gait_state", i / 200, state(i))
        rec.write("/torque", i / 200, torque(i))
        print(i / 200, flush=True)  # the sample is in the recorder's hands
        i += 1
        time.sleep(max(0.0, start + i / 200 - time.perf_counter()))
    """
)


def test_recover_after_sigkill_loses_at_most_the_flush_interval(tmp_path: Path) -> None:
    path = tmp_path / "killed.mcap"
    repo = Path(__file__).resolve().parents[3]
    proc = subprocess.Popen(
        [sys.executable, "-c", _CRASHING_RECORDER, str(path)], cwd=repo, stdout=subprocess.PIPE, text=True
    )
    printed: list[str] = []  # the times of the samples the child wrote, as it says them
    try:
        assert proc.stdout is not None and proc.stdout.readline() == "recording\n"
        started = time.monotonic()
        # ~1.5 s of recording, and at least one chunk on disk (header and metadata are < 1 kB): read as the
        # child says each sample is written, no polling
        for line in proc.stdout:
            printed.append(line)
            if float(line) >= 1.5 and path.stat().st_size >= 4096:
                break
            assert time.monotonic() - started < 10, "no chunk written within 10 s"
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        assert proc.stdout is not None
        printed += proc.stdout.read().split()  # what the child printed before it died
        proc.stdout.close()
    assert proc.returncode == -signal.SIGKILL
    last_written = float(printed[-1])  # the child may have written one more sample before the kill

    with pytest.raises(DataFormatError, match="not finished"):
        check_mcap(path)
    result = recover(path)
    assert result.recovered and result.messages > 0
    check_mcap(path)
    messages = list(read_messages(path))
    assert len(messages) == result.messages
    for topic in ("/sensor", "/gait_state", "/torque"):
        times = [m["t"] for name, _, m in messages if name == topic]
        assert len(times) > 100 and all(b > a for a, b in itertools.pairwise(times))
    log_times = [lt for _, lt, _ in messages]
    assert log_times == sorted(log_times)
    kept = max(m["t"] for name, _, m in messages if name == "/gait_state")
    assert last_written - FLUSH_INTERVAL_S <= kept <= last_written + 1 / RATE_HZ


# --- durability: time-based flush, fsync, full disk ---------------------------------------------


def on_disk(path: Path, scratch: Path) -> dict[str, list[float]]:
    """``t`` of each topic's messages in what the OS holds of ``path``: a copy, recovered as after a crash."""
    copy = scratch / f"copy-{path.name}"
    shutil.copyfile(path, copy)
    try:
        result = recover(copy)
        assert result.lost_bytes == 0  # the file ends at a record boundary
        out: dict[str, list[float]] = {}
        for topic, _, m in read_messages(copy):
            out.setdefault(topic, []).append(m["t"] if "t" in m else math.nan)
        return out
    finally:
        copy.unlink()


def latest(kept: dict[str, list[float]]) -> float | None:
    """The latest ``t`` of any message in :func:`on_disk`'s answer (None if none)."""
    return max((t for ts in kept.values() for t in ts), default=None)


def test_a_chunk_reaches_the_os_every_flush_interval_of_session_time(tmp_path: Path) -> None:
    path = tmp_path / "t.mcap"
    with Recorder(path, START_NS, {}) as rec:
        for i in range(201):  # 1.0 s at 200 Hz, written far faster than real time
            write_samples(rec, i, i + 1)
            if i % 25 == 0:
                t = i / RATE_HZ
                kept = on_disk(path, tmp_path).get("/gait_state", [])
                assert kept == [k / RATE_HZ for k in range(len(kept))]  # every sample, in order
                # The open chunk holds less than FLUSH_INTERVAL_S: all older data is in the file.
                assert t < FLUSH_INTERVAL_S or kept[-1] >= t - FLUSH_INTERVAL_S - 1e-9
                assert rec.saved_t == latest(on_disk(path, tmp_path))
        assert on_disk(path, tmp_path)["/gait_state"][-1] == 1.0 - 1 / RATE_HZ  # closed at /sensor t=1.0
        assert rec.saved_t == 1.0


def test_a_chunk_reaches_the_os_after_flush_interval_of_wall_time(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Messages at one session time (events after the source stopped): the wall clock closes the chunk.
    now = [1000.0]  # the recorder's monotonic clock, moved by the test
    monkeypatch.setattr(recording, "time", SimpleNamespace(monotonic=lambda: now[0]))
    path = tmp_path / "t.mcap"
    with Recorder(path, START_NS, {}, flush_interval_s=0.2) as rec:
        for i in range(5):
            rec.write("/gait_state", 3.0, state(i))
        now[0] += 0.19
        rec.write("/gait_state", 3.0, state(5))
        assert "/gait_state" not in on_disk(path, tmp_path)  # open 0.19 s: still in memory
        now[0] += 0.02
        rec.write("/gait_state", 3.0, state(6))
        assert on_disk(path, tmp_path)["/gait_state"] == [state(i).t for i in range(7)]  # their own t
        assert rec.saved_t == 3.0  # the session time they were logged at


def test_fsync_runs_on_a_worker_thread_and_at_finish(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[str] = []
    real_fsync = os.fsync

    def fsync(fd: int) -> None:
        calls.append(threading.current_thread().name)
        real_fsync(fd)

    monkeypatch.setattr(os, "fsync", fsync)
    with Recorder(tmp_path / "every.mcap", START_NS, {}, fsync_interval_s=0) as rec:
        write_samples(rec, 0, 201)  # the header, then two chunks: at 0.5 s and at 1.0 s
    workers = [name for name in calls if name != "MainThread"]
    # One at a time: a hand-over while the last fsync still runs starts none (they never pile up).
    assert 1 <= len(workers) <= 3 and set(workers) == {"fsync every.mcap"}
    assert calls[-1] == "MainThread"  # finish() waits for the worker, then syncs before it closes
    calls.clear()
    with Recorder(tmp_path / "never.mcap", START_NS, {}, fsync_interval_s=math.inf) as rec:
        write_samples(rec, 0, 201)
    assert calls == ["MainThread"]


def test_an_fsync_error_stops_the_recording(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    real_fsync, calls = os.fsync, []

    failing = threading.Event()

    def fsync(fd: int) -> None:  # the header's fsync works, the first chunk's fails
        calls.append(fd)
        if len(calls) > 1:
            failing.set()
            raise OSError(errno.EIO, "Input/output error")
        real_fsync(fd)

    monkeypatch.setattr(os, "fsync", fsync)
    path = tmp_path / "t.mcap"
    rec = Recorder(path, START_NS, {}, fsync_interval_s=0)
    taken, deadline = 0, time.monotonic() + 10
    with pytest.raises(RecordingError) as failed:  # the first chunk closes at 0.5 s; its fsync fails on
        for i in itertools.count():  # the worker thread, and a later write says so
            rec.write("/gait_state", i / RATE_HZ, state(i))
            taken += 1
            if i > 100:  # a chunk is handed over: write on until its fsync has failed and a write says so.
                # Not one long wait: the header's fsync may still be running when the first chunk is handed
                # over, and then the next chunk's is the first to fail (it starts only with a later write).
                failing.wait(0.001)
                assert time.monotonic() < deadline, "the fsync error was never raised"
    assert failed.value.errno == errno.EIO and taken > 100
    assert str(failed.value) == (
        "recording stopped: the disk could not be written (Input/output error); "
        "what was written may not all be on the disk"
    )
    with pytest.raises(RecordingError, match="may not all be on the disk"):  # and the final fsync fails
        rec.finish()
    monkeypatch.undo()
    check_mcap(path)  # written and indexed all the same; only its durability is in doubt
    seqs = [m["seq"] for _, _, m in read_messages(path, ["/gait_state"])]
    # Raised before the write took its message, or after the message's chunk was written.
    assert seqs in (list(range(taken)), list(range(taken + 1)))


class _SmallDisk:
    """Stands in for ``recording._write_all`` on a disk with ``room`` bytes left: a longer write is
    cut short where the room ends and raises ENOSPC, as a full disk does."""

    def __init__(self, room: int):
        self.room = room

    def write_all(self, file: io.FileIO, data: bytes) -> None:
        if len(data) > self.room:
            file.write(data[: self.room])
            self.room = 0
            raise OSError(errno.ENOSPC, "No space left on device")
        file.write(data)
        self.room -= len(data)


def _record_until_full(rec: Recorder, limit: int = 200 * 600) -> tuple[int, list[tuple[str, int]]]:
    """Write samples until a RecordingError: (the failing sample, every (topic, seq) the recorder took)."""
    taken: list[tuple[str, int]] = []
    for i in range(limit):
        for topic, message in (("/sensor", frame(i)), ("/gait_state", state(i)), ("/torque", torque(i))):
            try:
                rec.write(topic, i / RATE_HZ, message)
            except RecordingError as e:
                assert e.errno == errno.ENOSPC
                taken.append((topic, i))  # in the failed chunk, held for finish() to retry
                return i, taken
            taken.append((topic, i))
    raise AssertionError(f"the disk did not fill in {limit} samples")


@pytest.mark.parametrize("room_at_finish", [False, True], ids=["disk-stays-full", "room-freed"])
def test_a_full_disk_keeps_the_data_up_to_the_failure(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, room_at_finish: bool
) -> None:
    disk = _SmallDisk(room=120_000)
    monkeypatch.setattr(recording, "_write_all", disk.write_all)
    path = tmp_path / "t.mcap"
    rec = Recorder(path, START_NS, META)
    failed_at, taken = _record_until_full(rec)
    t_fail = failed_at / RATE_HZ
    assert rec.error is not None
    assert str(rec.error) == f"recording stopped: the disk is full; data up to {rec.saved_t:.1f} s is kept"
    assert str(tmp_path) not in str(rec.error) and rec.error.filename == str(path)
    assert rec.saved_t is not None and rec.saved_t >= t_fail - FLUSH_INTERVAL_S - 1e-9
    with pytest.raises(RecordingError, match="the disk is full"):  # refused from now on
        rec.write("/torque", t_fail, torque(failed_at))
    kept = on_disk(path, tmp_path)  # the torn write was cut off: the file ends at a record boundary
    assert latest(kept) == rec.saved_t

    if room_at_finish:
        disk.room = 10**9
        rec.finish()
        check_mcap(path)  # complete and indexed: nothing lost up to the failure
        got = [(topic, m["seq"]) for topic, _, m in read_messages(path, ["/sensor", "/gait_state", "/torque"])]
        assert sorted(got) == sorted(taken)
    else:
        with pytest.raises(RecordingError, match="the disk is full"):
            rec.finish()
        result = recover(path)  # what start-up recovery does once there is room
        assert result.recovered and result.lost_bytes == 0
        seqs = [m["seq"] for _, _, m in read_messages(path, ["/gait_state"])]
        assert seqs == list(range(len(kept["/gait_state"])))
        assert seqs[-1] / RATE_HZ >= t_fail - FLUSH_INTERVAL_S - 1 / RATE_HZ - 1e-9  # lost: the failed chunk


def test_no_room_for_the_header_leaves_no_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(recording, "_write_all", _SmallDisk(room=10).write_all)
    path = tmp_path / "t.mcap"
    with pytest.raises(RecordingError, match=r"^recording stopped: the disk is full; no data is kept$"):
        Recorder(path, START_NS, META)
    assert not path.exists()


@pytest.fixture
def tmpfs(tmp_path: Path) -> Iterator[Path]:
    """A real 2 MiB file system (tmpfs): needs root on Linux, else the test is skipped."""
    where = tmp_path / "tmpfs"
    where.mkdir()
    if sys.platform != "linux" or os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root on Linux; the simulated full disk covers the same code")
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(where)], capture_output=True, text=True, check=False
    )
    if mounted.returncode != 0:
        pytest.skip(f"mounting a tmpfs is not permitted here ({mounted.stderr.strip()})")
    try:
        yield where
    finally:
        subprocess.run(["umount", str(where)], check=True)


@pytest.mark.parametrize("room_at_finish", [False, True], ids=["disk-stays-full", "room-freed"])
def test_a_real_full_disk_keeps_the_data_up_to_the_failure(tmp_path: Path, tmpfs: Path, room_at_finish: bool) -> None:
    filler = tmpfs / "filler"
    filler.write_bytes(b"\0" * (1024 * 1024))  # half the disk, freed before finish() in one case
    path = tmpfs / "recordings" / "t.mcap"
    rec = Recorder(path, START_NS, META)
    failed_at, taken = _record_until_full(rec)
    t_fail = failed_at / RATE_HZ
    assert t_fail > 10  # about 1 MiB at ~29 KiB/s
    assert str(rec.error) == f"recording stopped: the disk is full; data up to {rec.saved_t:.1f} s is kept"
    if room_at_finish:
        filler.unlink()
        rec.finish()
        check_mcap(path)
        got = [(topic, m["seq"]) for topic, _, m in read_messages(path, ["/sensor", "/gait_state", "/torque"])]
        assert sorted(got) == sorted(taken)
    else:
        with pytest.raises(RecordingError, match="the disk is full"):
            rec.finish()
        copy = tmp_path / "copy.mcap"  # recovered where there is room, as after freeing space
        shutil.copyfile(path, copy)
        result = recover(copy)
        assert result.recovered and result.lost_bytes == 0
        seqs = [m["seq"] for _, _, m in read_messages(copy, ["/gait_state"])]
        assert seqs == list(range(len(seqs)))
        assert seqs[-1] / RATE_HZ >= t_fail - FLUSH_INTERVAL_S - 1 / RATE_HZ - 1e-9  # lost: the failed chunk


def test_series_of_a_long_recording_needs_memory_for_max_points_only(tmp_path: Path) -> None:
    import tracemalloc

    from gaitscope.sessions.schema import GaitState

    path = tmp_path / "long.mcap"
    n = 30_000  # 2.5 min at 200 Hz
    base = dict(phase=0.1, phase_rate=1.0, stride_length_m=1.3, incline_deg=0.0, torque_Nm=1.0, tbe_phase=0.1,
                heel_strike=False, backup_reset=False, foot_angle_deg=1.0, shank_angle_deg=2.0, thigh_angle_deg=None,
                foot_pred_deg=1.0, shank_pred_deg=2.0, recv_ns=0)  # fmt: skip
    with Recorder(path, 10**18, {}) as rec:
        for k in range(n):
            rec.write("/gait_state", k * 0.005, GaitState(seq=k, t=k * 0.005, **base))
    tracemalloc.start()
    series = read_series(path, None, None, max_points=1000)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert len(series["t"]) == 1000 and series["t"][0] == 0.0 and series["t"][-1] == pytest.approx((n - 1) * 0.005)
    assert peak < 8 * 2**20  # every state as a dict would take far more (about 1 kB each)

"""Reading recordings across sensor-frame versions: a version 1 file (written before ``version`` existed)
reads as version 2 frames; a file written now says version 2."""

from __future__ import annotations

import json
from pathlib import Path

from mcap.writer import Writer

from gaitscope.sessions import schema
from gaitscope.sessions.formats.mcap_io import check_mcap, iter_sensor_frames, read_messages, read_sensor_frames
from gaitscope.sessions.formats.recording import Recorder

START_NS = 1_700_000_000_000_000_000
#: The /sensor JSON schema version 1 recordings carry (gaitscope.SensorFrame before the channel registry).
V1_SCHEMA = {
    "title": "SensorFrame",
    "type": "object",
    "additionalProperties": False,
    "required": ["seq", "t"],
    "properties": {
        "type": {"const": "frame", "default": "frame", "type": "string"},
        "seq": {"type": "integer", "minimum": 0},
        "t": {"type": "number"},
        **{
            name: {"anyOf": [{"type": "number"}, {"type": "null"}], "default": None}
            for name in (*schema.REPLAY_SIGNALS, "thigh_angle_deg")
        },
        "heel_strike": {"anyOf": [{"type": "boolean"}, {"type": "null"}], "default": None},
        "sent_ns": {"anyOf": [{"type": "integer"}, {"type": "null"}], "default": None},
    },
}


def v1_frame(i: int) -> dict[str, object]:
    """A version 1 frame as the version 1 recorder wrote it: every field, absent channels as null."""
    return {
        "type": "frame",
        "seq": i,
        "t": i / 100,
        "foot_angle_deg": 10.0 + i,
        "foot_vel_dps": -50.0 + i,
        "shank_angle_deg": 2.5,
        "shank_vel_dps": None if i % 3 == 0 else 30.0,
        "heel_forward_m": 0.125,
        "heel_up_m": -0.5,
        "thigh_angle_deg": None,
        "heel_strike": i == 4,
        "sent_ns": None,
    }


def write_v1_recording(path: Path, n: int) -> None:
    """A finished version 1 trial file: header, metadata, the /sensor channel with its old schema."""
    with path.open("wb") as f:
        writer = Writer(f)
        writer.start(profile="", library="gaitscope")
        writer.add_metadata("gaitscope", {"subject": "S01", "start_ns": str(START_NS)})
        sid = writer.register_schema(
            name="gaitscope.SensorFrame", encoding="jsonschema", data=json.dumps(V1_SCHEMA).encode()
        )
        cid = writer.register_channel(topic="/sensor", message_encoding="json", schema_id=sid)
        for i in range(n):
            log_time = START_NS + i * 10_000_000
            writer.add_message(cid, log_time=log_time, data=json.dumps(v1_frame(i)).encode(), publish_time=log_time)
        writer.finish()


def test_a_version_1_recording_reads_as_version_2_frames(tmp_path: Path) -> None:
    path = tmp_path / "old.mcap"
    write_v1_recording(path, 12)
    check_mcap(path)
    raw = [data for _, _, data in read_messages(path, ["/sensor"])]
    assert all("version" not in d for d in raw)  # the file holds version 1 frames
    frames = read_sensor_frames(path)
    assert [f.version for f in frames] == [2] * 12
    for frame, old in zip(frames, raw, strict=True):
        assert frame.model_dump(exclude={"version"}, include=set(old)) == old  # every value kept
        assert schema.missing_channels(["foot_angle_deg", "hip_angle_deg"], frame) == ["hip_angle_deg"]
    assert [t for t, _ in iter_sensor_frames(path)] == [START_NS + i * 10_000_000 for i in range(12)]
    assert frames[4].heel_strike is True and frames[3].shank_vel_dps is None


def test_a_recording_written_now_says_version_2(tmp_path: Path) -> None:
    path = tmp_path / "new.mcap"
    frame = schema.SensorFrame(seq=0, t=0.0, foot_angle_deg=1.0, imu_foot_gyro_z_dps=-120.5, foot_contact=True)
    with Recorder(path, START_NS, {"subject": "S01"}) as rec:
        rec.write("/sensor", 0.0, frame)
    (data,) = [d for _, _, d in read_messages(path, ["/sensor"])]
    assert data["version"] == 2 and data["imu_foot_gyro_z_dps"] == -120.5
    assert read_sensor_frames(path) == [frame]

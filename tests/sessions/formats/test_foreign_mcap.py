"""MCAP files from other tools (JSON, Protobuf, ROS 2), written here with the mcap writers into tmp_path: inspected,
mapped and streamed as sensor frames."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from google.protobuf import descriptor_pb2, descriptor_pool, timestamp_pb2
from google.protobuf.message_factory import GetMessageClass
from mcap.writer import Writer
from mcap_protobuf.writer import Writer as ProtobufWriter
from mcap_ros2.writer import Writer as Ros2Writer

from gaitscope.sessions import schema
from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.formats import foreign_mcap
from gaitscope.sessions.formats.foreign_mcap import (
    RAD_TO_DEG,
    ChannelMapping,
    FieldInfo,
    MappingEntry,
    MappingError,
    RigMismatch,
    foreign_frames,
    inspect_mcap,
    rig_signature,
    suggest_mapping,
    undecodable_topics,
)
from gaitscope.sessions.formats.recording import Recorder

T0 = 1_700_000_000_000_000_000  # log time of the first message (ns)
MS = 1_000_000

# --- ROS 2 -----------------------------------------------------------------------------------------------------

HEADER = "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n"
SEP = "=" * 80 + "\n"
JOINT_STATE = (
    "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n" + SEP + HEADER
)
VECTOR3 = "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n"
QUATERNION = "MSG: geometry_msgs/Quaternion\nfloat64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n"
IMU = (
    "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\n"
    "geometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\n"
    "geometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance\n"
    + SEP
    + HEADER
    + SEP
    + QUATERNION
    + SEP
    + VECTOR3
)


def knee_rad(i: int) -> float:
    """The JointState's knee angle (rad) of message i."""
    return 0.01 * i


def gyro_z(i: int) -> float:
    """The shank IMU's rate about z (rad/s) of message i."""
    return 0.1 + 0.001 * i


def stamp(ns: int) -> dict[str, int]:
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def write_ros2(
    path: Path, *, joints: int = 50, imus: int = 100, skip_joints: range = range(0), extra_topic: bool = False
) -> Path:
    """/joint_states at 100 Hz (hip, knee, ankle; radians), /imu/shank at 200 Hz, both stamped 3 ms before
    their log time; ``skip_joints`` leaves a gap in the joint states."""
    with path.open("wb") as f:
        w = Ros2Writer(f)
        js = w.register_msgdef("sensor_msgs/msg/JointState", JOINT_STATE)
        imu = w.register_msgdef("sensor_msgs/msg/Imu", IMU)
        for i in range(imus):
            log = T0 + 5 * MS * i
            if i % 2 == 0 and i // 2 < joints and i // 2 not in skip_joints:
                j = i // 2
                msg = {
                    "header": {"stamp": stamp(log - 3 * MS), "frame_id": ""},
                    "name": ["hip", "knee", "ankle"],
                    "position": [0.5, knee_rad(j), -0.1],
                    "velocity": [0.0, 1.0, 0.0],
                    "effort": [],
                }
                w.write_message("/joint_states", js, msg, log_time=log, publish_time=log)
            msg = {
                "header": {"stamp": stamp(log - 3 * MS), "frame_id": "shank"},
                "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
                "orientation_covariance": [0.0] * 9,
                "angular_velocity": {"x": 0.0, "y": 0.0, "z": gyro_z(i)},
                "angular_velocity_covariance": [0.0] * 9,
                "linear_acceleration": {"x": 0.0, "y": 9.81, "z": 0.0},
                "linear_acceleration_covariance": [0.0] * 9,
            }
            w.write_message("/imu/shank", imu, msg, log_time=log, publish_time=log)
        if extra_topic:
            w.write_message("/imu/thigh", imu, msg, log_time=log, publish_time=log)
        w.finish()
    return path


# --- JSON ------------------------------------------------------------------------------------------------------


def write_json(path: Path, messages: list[tuple[str, int, dict[str, Any]]], empty_topics: tuple[str, ...] = ()) -> Path:
    """``messages`` as (topic, log time, object), each topic with a jsonschema named ``custom<topic>``."""
    with path.open("wb") as f:
        w = Writer(f)
        w.start(profile="", library="test")
        channels: dict[str, int] = {}
        for topic in [*dict.fromkeys(t for t, _, _ in messages), *empty_topics]:
            sid = w.register_schema(f"custom{topic}", "jsonschema", b'{"type": "object"}')
            channels[topic] = w.register_channel(topic, "json", sid)
        for topic, log, obj in messages:
            w.add_message(channels[topic], log, json.dumps(obj).encode(), log)
        w.finish()
    return path


def exo_messages(n: int = 20) -> list[tuple[str, int, dict[str, Any]]]:
    """/exo at 100 Hz: a knee angle in degrees, a heel strike at message 5, text and a nested object."""
    return [
        ("/exo", T0 + 10 * MS * i, {"knee": 2.0 * i, "heel_strike": i == 5, "mode": "walk", "motor": {"current": 1.5}})
        for i in range(n)
    ]


# --- Protobuf --------------------------------------------------------------------------------------------------


def imu_sample_class() -> Any:
    """A Protobuf message class built at run time: ``test.ImuSample`` (a Foxglove-style ``timestamp``)."""
    pool = descriptor_pool.DescriptorPool()
    ts = descriptor_pb2.FileDescriptorProto()
    timestamp_pb2.DESCRIPTOR.CopyToProto(ts)
    pool.Add(ts)
    fd = descriptor_pb2.FileDescriptorProto(name="test/imu.proto", package="test", syntax="proto3")
    fd.dependency.append("google/protobuf/timestamp.proto")
    F = descriptor_pb2.FieldDescriptorProto
    vec = fd.message_type.add(name="Vector3")
    for number, axis in enumerate("xyz", 1):
        vec.field.add(name=axis, number=number, type=F.TYPE_DOUBLE, label=F.LABEL_OPTIONAL)
    msg = fd.message_type.add(name="ImuSample")
    msg.field.add(
        name="timestamp", number=1, type=F.TYPE_MESSAGE, type_name=".google.protobuf.Timestamp", label=F.LABEL_OPTIONAL
    )
    msg.field.add(
        name="angular_velocity", number=2, type=F.TYPE_MESSAGE, type_name=".test.Vector3", label=F.LABEL_OPTIONAL
    )
    msg.field.add(name="extra", number=3, type=F.TYPE_DOUBLE, label=F.LABEL_REPEATED)
    msg.field.add(name="contact", number=4, type=F.TYPE_BOOL, label=F.LABEL_OPTIONAL)
    msg.field.add(name="label", number=5, type=F.TYPE_STRING, label=F.LABEL_OPTIONAL)
    pool.Add(fd)
    return GetMessageClass(pool.FindMessageTypeByName("test.ImuSample"))


def write_protobuf(path: Path, n: int = 30) -> Path:
    """/thigh_imu at 50 Hz: angular_velocity.z = i rad/s, contact while i < 10, timestamp = log time."""
    cls = imu_sample_class()
    with path.open("wb") as f, ProtobufWriter(f) as w:
        for i in range(n):
            log = T0 + 20 * MS * i
            msg = cls(label="L", contact=i < 10, extra=[1.0, 2.0])
            msg.timestamp.seconds, msg.timestamp.nanos = divmod(log, 1_000_000_000)
            msg.angular_velocity.z = float(i)
            w.write_message("/thigh_imu", msg, log_time=log, publish_time=log)
    return path


def fields_of(fields: list[FieldInfo], topic: str) -> dict[str, FieldInfo]:
    return {f.path: f for f in fields if f.topic == topic}


# --- inspection ------------------------------------------------------------------------------------------------


def test_inspect_ros2(tmp_path: Path) -> None:
    path = write_ros2(tmp_path / "ros.mcap")
    fields = inspect_mcap(path, "ros.mcap")
    assert [f.topic for f in fields] == sorted(f.topic for f in fields)
    js = fields_of(fields, "/joint_states")
    assert list(js) == [f"{a}[{j}]" for a in ("position", "velocity") for j in ("hip", "knee", "ankle")]
    knee = js["position[knee]"]
    assert (knee.kind, knee.message_encoding, knee.schema_name) == ("number", "cdr", "sensor_msgs/msg/JointState")
    assert (knee.count, knee.sampled, knee.present) == (50, 50, 50)
    assert knee.rate_hz == pytest.approx(100.0)
    assert (knee.min, knee.max) == (0.0, pytest.approx(knee_rad(49)))
    assert knee.time_source == "log_time"
    imu = fields_of(fields, "/imu/shank")
    assert "header.stamp.sec" not in imu and "header.frame_id" not in imu  # time and text are not fields
    assert list(imu)[:4] == ["orientation.x", "orientation.y", "orientation.z", "orientation.w"]
    assert len(imu) == 4 + 3 * 9 + 3 + 3
    assert imu["orientation_covariance[8]"].kind == "number"
    z = imu["angular_velocity.z"]
    assert (z.count, z.rate_hz, z.min, z.max) == (100, pytest.approx(200.0), gyro_z(0), pytest.approx(gyro_z(99)))
    assert {f.rig for f in fields} == {rig_signature(path)}


def test_inspect_reads_a_bounded_sample_and_header_stamps(tmp_path: Path) -> None:
    path = write_ros2(tmp_path / "ros.mcap")
    fields = inspect_mcap(path, "ros.mcap", sample_messages=10, time_source="header")
    knee = fields_of(fields, "/joint_states")["position[knee]"]
    assert (knee.count, knee.sampled, knee.max) == (50, 10, pytest.approx(knee_rad(9)))
    assert (knee.time_source, knee.rate_hz) == ("header", pytest.approx(100.0))
    with pytest.raises(ValueError, match="sample_messages"):
        inspect_mcap(path, "ros.mcap", sample_messages=0)


def test_inspect_json_and_protobuf(tmp_path: Path) -> None:
    fields = inspect_mcap(write_json(tmp_path / "j.mcap", exo_messages()), "j.mcap")
    assert [(f.path, f.kind) for f in fields] == [
        ("knee", "number"),
        ("heel_strike", "bool"),
        ("motor.current", "number"),
    ]
    knee, strike = fields[0], fields[1]
    assert (knee.message_encoding, knee.schema_name, knee.count, knee.min, knee.max) == (
        "json",
        "custom/exo",
        20,
        0,
        38,
    )
    assert knee.rate_hz == pytest.approx(100.0)
    assert (strike.min, strike.max, strike.present) == (0.0, 1.0, 20)

    fields = inspect_mcap(write_protobuf(tmp_path / "p.mcap"), "p.mcap", time_source="header")
    assert [(f.path, f.kind) for f in fields] == [
        ("angular_velocity.x", "number"),
        ("angular_velocity.y", "number"),
        ("angular_velocity.z", "number"),
        ("extra[0]", "number"),
        ("extra[1]", "number"),
        ("contact", "bool"),
    ]  # timestamp.seconds/nanos: the stamp; label: text
    z = fields[2]
    assert (z.message_encoding, z.schema_name, z.time_source) == ("protobuf", "test.ImuSample", "header")
    assert (z.min, z.max, z.rate_hz) == (0.0, 29.0, pytest.approx(50.0))


def write_gaitscope(path: Path, n: int = 40) -> Path:
    """A recording gaitscope's own Recorder writes: /sensor at 200 Hz with a knee angle and a shank gyro."""
    rec = Recorder(path, T0, {"subject": "S01"})
    for i in range(n):
        frame = schema.SensorFrame(
            seq=i, t=i / 200, knee_angle_deg=float(i), imu_shank_gyro_z_dps=-float(i), heel_strike=i == 3
        )
        rec.write("/sensor", i / 200, frame)
    rec.finish()
    return path


def test_inspect_a_gaitscope_recording(tmp_path: Path) -> None:
    fields = inspect_mcap(write_gaitscope(tmp_path / "g.mcap"), "g.mcap")
    sensor = fields_of(fields, "/sensor")
    assert list(sensor) == ["version", "seq", "t", "knee_angle_deg", "imu_shank_gyro_z_dps", "heel_strike"]
    knee = sensor["knee_angle_deg"]
    assert (knee.schema_name, knee.message_encoding, knee.count, knee.max) == ("gaitscope.SensorFrame", "json", 40, 39)
    assert knee.rate_hz == pytest.approx(200.0)


def test_undecodable_topics_are_named_and_left_out(tmp_path: Path) -> None:
    path = tmp_path / "x.mcap"
    with path.open("wb") as f:
        w = Writer(f)
        w.start(profile="", library="test")
        sid = w.register_schema("pkg/Thing", "ros1msg", b"float64 x")
        cid = w.register_channel("/ros1", "ros1", sid)
        w.add_message(cid, T0, b"\x00" * 8, T0)
        w.finish()
    assert inspect_mcap(path) == []
    assert "'ros1' messages, which gaitscope cannot decode" in undecodable_topics(path)["/ros1"]


def test_files_that_are_not_finished_mcap(tmp_path: Path) -> None:
    (tmp_path / "a.mcap").write_bytes(b"hello")
    with pytest.raises(DataFormatError, match=r"file a\.mcap: not an MCAP file"):
        inspect_mcap(tmp_path / "a.mcap", "a.mcap")
    whole = write_json(tmp_path / "b.mcap", exo_messages()).read_bytes()
    (tmp_path / "c.mcap").write_bytes(whole[: len(whole) // 2])
    with pytest.raises(DataFormatError, match="not finished"):
        inspect_mcap(tmp_path / "c.mcap", "c.mcap")


# --- mappings --------------------------------------------------------------------------------------------------


def test_suggest_mapping_ros2(tmp_path: Path) -> None:
    path = write_ros2(tmp_path / "ros.mcap")
    mapping = suggest_mapping(inspect_mcap(path))
    assert mapping.rig == rig_signature(path)
    assert mapping.time_source == "log_time"
    assert set(mapping.entries) == {
        MappingEntry("/joint_states", "position[hip]", "hip_angle_deg", RAD_TO_DEG),
        MappingEntry("/joint_states", "position[knee]", "knee_angle_deg", RAD_TO_DEG),
        MappingEntry("/joint_states", "position[ankle]", "ankle_angle_deg", RAD_TO_DEG),
        *(MappingEntry("/imu/shank", f"angular_velocity.{a}", f"imu_shank_gyro_{a}_dps", RAD_TO_DEG) for a in "xyz"),
        *(MappingEntry("/imu/shank", f"linear_acceleration.{a}", f"imu_shank_accel_{a}_m_s2") for a in "xyz"),
    }
    assert suggest_mapping(inspect_mcap(path, time_source="header")).time_source == "header"


def test_suggest_mapping_json_protobuf_and_gaitscope(tmp_path: Path) -> None:
    mapping = suggest_mapping(inspect_mcap(write_json(tmp_path / "j.mcap", exo_messages())))
    assert mapping.entries == (
        MappingEntry("/exo", "heel_strike", "heel_strike"),  # a channel's own name comes first
        MappingEntry("/exo", "knee", "knee_angle_deg"),  # degrees: no "rad" in the name
    )
    rad = [("/exo", T0, {"left_knee_rad": 1.0, "knee_vel": 2.0, "contra": {"hip": 3.0}})]
    mapping = suggest_mapping(inspect_mcap(write_json(tmp_path / "r.mcap", rad)))
    assert mapping.entries == (
        MappingEntry("/exo", "left_knee_rad", "knee_angle_deg", RAD_TO_DEG),
        MappingEntry("/exo", "contra.hip", "hip_angle_contra_deg"),
    )
    protobuf = suggest_mapping(inspect_mcap(write_protobuf(tmp_path / "p.mcap")))
    assert protobuf.entries == (
        *(MappingEntry("/thigh_imu", f"angular_velocity.{a}", f"imu_thigh_gyro_{a}_dps", RAD_TO_DEG) for a in "xyz"),
        MappingEntry("/thigh_imu", "contact", "foot_contact"),
    )
    own = suggest_mapping(inspect_mcap(write_gaitscope(tmp_path / "g.mcap")))
    assert [(e.topic, e.field, e.channel, e.scale) for e in own.entries] == [
        ("/sensor", c, c, 1.0) for c in ("knee_angle_deg", "imu_shank_gyro_z_dps", "heel_strike")
    ]
    assert suggest_mapping([]) == ChannelMapping((), "")


def test_mapping_json_round_trip_and_validation() -> None:
    mapping = ChannelMapping(
        [MappingEntry("/joint_states", "position[knee]", "knee_angle_deg", RAD_TO_DEG, 2.5)], "abc", "header"
    )
    assert isinstance(mapping.entries, tuple)
    text = mapping.to_json()
    assert json.loads(text)["entries"][0] == {
        "topic": "/joint_states",
        "field": "position[knee]",
        "channel": "knee_angle_deg",
        "scale": RAD_TO_DEG,
        "offset": 2.5,
    }
    assert ChannelMapping.from_json(text) == mapping
    assert ChannelMapping.from_json(text.encode()) == mapping

    with pytest.raises(
        MappingError, match=r"unknown gaitscope channels: 'knee_angel_deg' \(did you mean 'knee_angle_deg'"
    ):
        ChannelMapping([MappingEntry("/a", "x", "knee_angel_deg")], "")
    with pytest.raises(MappingError, match=r"'zzz' \(no close match\)"):
        ChannelMapping([MappingEntry("/a", "x", "knee_angle_deg"), MappingEntry("/a", "y", "zzz")], "")
    with pytest.raises(MappingError, match="more than one field: 'knee_angle_deg'"):
        ChannelMapping([MappingEntry("/a", "x", "knee_angle_deg"), MappingEntry("/b", "x", "knee_angle_deg")], "")
    with pytest.raises(MappingError, match="heel_strike is a flag"):
        ChannelMapping([MappingEntry("/a", "x", "heel_strike", -1.0)], "")
    with pytest.raises(MappingError, match="scale must be finite and not 0"):
        ChannelMapping([MappingEntry("/a", "x", "knee_angle_deg", 0.0)], "")
    with pytest.raises(MappingError, match="time_source"):
        ChannelMapping([], "", "wall")  # type: ignore[arg-type]

    data = json.loads(text)
    bad: list[tuple[Callable[[dict[str, Any]], object], str]] = [
        (lambda d: d.update(version=2), "mapping version 2"),
        (lambda d: d.pop("rig"), r"missing keys \['rig'\]"),
        (lambda d: d["entries"][0].update(unit="deg"), r"entry 1: missing keys \[\], unknown keys \['unit'\]"),
        (lambda d: d["entries"][0].update(scale="1"), "entry 1: 'scale' must be a JSON float"),
        (lambda d: d["entries"][0].update(channel="knee"), "unknown gaitscope channels: 'knee'"),
    ]
    for change, message in bad:
        d = json.loads(text)
        change(d)
        with pytest.raises(MappingError, match=message):
            ChannelMapping.from_json(json.dumps(d))
    with pytest.raises(MappingError, match="must be JSON"):
        ChannelMapping.from_json("{")
    assert data["version"] == 1


def test_rig_signature(tmp_path: Path) -> None:
    short = rig_signature(write_ros2(tmp_path / "a.mcap", joints=5, imus=10))
    assert len(short) == 16
    assert rig_signature(write_ros2(tmp_path / "b.mcap")) == short  # same topics and types, other length
    assert rig_signature(write_ros2(tmp_path / "c.mcap", extra_topic=True)) != short
    assert rig_signature(write_json(tmp_path / "d.mcap", exo_messages())) != short


# --- streaming -------------------------------------------------------------------------------------------------


ROS_MAPPING = [
    MappingEntry("/joint_states", "position[knee]", "knee_angle_deg", RAD_TO_DEG),
    MappingEntry("/imu/shank", "angular_velocity.z", "imu_shank_gyro_z_dps", -RAD_TO_DEG, 1.0),
]


def test_frames_on_the_fastest_topic_with_hold(tmp_path: Path) -> None:
    path = write_ros2(tmp_path / "ros.mcap")
    frames = list(foreign_frames(path, "ros.mcap", ChannelMapping(ROS_MAPPING, rig_signature(path))))
    assert len(frames) == 100  # /imu/shank's 200 Hz, not /joint_states' 100 Hz
    assert [f.seq for f in frames] == list(range(100))
    assert [f.t for f in frames] == pytest.approx([i * 0.005 for i in range(100)])
    for i, f in enumerate(frames):
        assert f.imu_shank_gyro_z_dps == pytest.approx(-gyro_z(i) * RAD_TO_DEG + 1.0)
        assert f.knee_angle_deg == pytest.approx(math.degrees(knee_rad(i // 2)))  # odd frames hold the last
        assert f.heel_strike is None and f.shank_angle_deg is None


def test_staleness(tmp_path: Path) -> None:
    path = write_ros2(tmp_path / "ros.mcap", skip_joints=range(10, 40))  # no joint state from 0.1 s to 0.4 s
    mapping = ChannelMapping(ROS_MAPPING, rig_signature(path))
    knee = [f.knee_angle_deg for f in foreign_frames(path, None, mapping)]
    # last joint state at frame 18 (0.09 s); still fresh up to 0.1 s later (frame 38), absent until frame 80
    assert knee[18] == knee[38] == pytest.approx(math.degrees(knee_rad(9)))
    assert knee[39:80] == [None] * 41
    assert knee[80] == pytest.approx(math.degrees(knee_rad(40)))
    held = [f.knee_angle_deg for f in foreign_frames(path, None, mapping, stale_s=math.inf)]
    assert held[39:80] == [held[18]] * 41


def test_frames_at_a_given_rate(tmp_path: Path) -> None:
    path = write_ros2(tmp_path / "ros.mcap")
    mapping = ChannelMapping(ROS_MAPPING, rig_signature(path))
    frames = list(foreign_frames(path, None, mapping, rate_hz=40.0))
    assert len(frames) == 20  # 0 to 0.495 s every 25 ms
    assert [f.t for f in frames] == pytest.approx([k * 0.025 for k in range(20)])
    for k, f in enumerate(frames):
        # at 25k ms: IMU message 5k (every 5 ms), joint state 2k + 1 at 10 ms steps holds from 20k + 10 ms
        assert f.imu_shank_gyro_z_dps == pytest.approx(-gyro_z(5 * k) * RAD_TO_DEG + 1.0)
        assert f.knee_angle_deg == pytest.approx(math.degrees(knee_rad((25 * k) // 10)))
    with pytest.raises(ValueError, match="rate_hz"):
        foreign_frames(path, None, mapping, rate_hz=0.0)


def test_heel_strike_is_an_event_and_text_values_are_refused(tmp_path: Path) -> None:
    messages = [
        *exo_messages(),
        *(("/imu/shank", T0 + 5 * MS * i, {"angular_velocity": {"z": 1.0}}) for i in range(40)),
    ]
    path = write_json(tmp_path / "j.mcap", sorted(messages, key=lambda m: m[1]))
    mapping = ChannelMapping(
        [
            MappingEntry("/exo", "heel_strike", "heel_strike"),
            MappingEntry("/exo", "knee", "knee_angle_deg"),
            MappingEntry("/imu/shank", "angular_velocity.z", "imu_shank_gyro_z_dps", RAD_TO_DEG),
        ],
        rig_signature(path),
    )
    frames = list(foreign_frames(path, "j.mcap", mapping))
    assert len(frames) == 40
    assert [i for i, f in enumerate(frames) if f.heel_strike] == [10]  # /exo message 5 at 50 ms
    assert all(f.heel_strike is False for i, f in enumerate(frames) if i != 10)
    assert frames[11].knee_angle_deg == 10.0

    later_text: list[tuple[str, int, dict[str, Any]]] = [
        ("/exo", T0, {"knee": 1.0}),
        ("/exo", T0 + 10 * MS, {"knee": "n/a"}),
    ]
    path = write_json(tmp_path / "t.mcap", later_text)
    frames_of = foreign_frames(path, "t.mcap", ChannelMapping([MappingEntry("/exo", "knee", "knee_angle_deg")], ""))
    with pytest.raises(DataFormatError, match=r"column '/exo knee', row 2: the mapped field is text \('n/a'\)"):
        list(frames_of)


def test_header_stamps_reorder_the_messages(tmp_path: Path) -> None:
    """/late is logged 40 ms after it was stamped: by stamp it comes before /fast's messages logged earlier."""
    fast = [("/fast", T0 + 10 * MS * i, {"timestamp": {"sec": 0, "nsec": 10 * MS * i}, "x": i}) for i in range(1, 30)]
    late = [
        ("/late", T0 + 10 * MS * i + 40 * MS, {"timestamp": {"sec": 0, "nsec": 10 * MS * i}, "knee": i})
        for i in range(1, 10)
    ]
    path = write_json(tmp_path / "h.mcap", sorted(fast + late, key=lambda m: m[1]))
    entries = [MappingEntry("/fast", "x", "shank_angle_deg"), MappingEntry("/late", "knee", "knee_angle_deg")]
    by_stamp = list(foreign_frames(path, None, ChannelMapping(entries, "", "header")))
    assert [(f.shank_angle_deg, f.knee_angle_deg) for f in by_stamp[:9]] == [(i, i) for i in range(1, 10)]
    by_log = list(foreign_frames(path, None, ChannelMapping(entries, "")))
    assert [f.knee_angle_deg for f in by_log[:6]] == [None, None, None, None, 1, 2]
    assert [f.t for f in by_stamp] == pytest.approx([0.01 * i for i in range(29)])


def test_a_gaitscope_recording_streams_back(tmp_path: Path) -> None:
    path = write_gaitscope(tmp_path / "g.mcap")
    frames = list(foreign_frames(path, None, suggest_mapping(inspect_mcap(path))))
    assert [(f.seq, f.knee_angle_deg, f.imu_shank_gyro_z_dps) for f in frames] == [(i, i, -i) for i in range(40)]
    assert [f.t for f in frames] == pytest.approx([i / 200 for i in range(40)])
    assert [f.seq for f in frames if f.heel_strike] == [3]


def test_mapping_errors_in_the_users_terms(tmp_path: Path) -> None:
    path = write_ros2(tmp_path / "ros.mcap")
    rig = rig_signature(path)

    def error(entries: list[MappingEntry], **kw: Any) -> str:
        with pytest.raises(DataFormatError) as info:
            foreign_frames(path, "ros.mcap", ChannelMapping(entries, kw.pop("rig", rig)), **kw)
        return str(info.value)

    assert error([MappingEntry("/imu/shin", "angular_velocity.z", "imu_shank_gyro_z_dps")]) == (
        "file ros.mcap, column '/imu/shin': the mapped topic /imu/shin is not in the file; close: /imu/shank"
    )
    assert error([MappingEntry("/joint_states", "position[kne]", "knee_angle_deg")]) == (
        "file ros.mcap, column '/joint_states position[kne]': the mapped field is not in the topic's messages; "
        "close: position[knee], position[ankle], position[hip]"
    )
    assert error([MappingEntry("/imu/shank", "angular_velocity", "imu_shank_gyro_z_dps")]).endswith(
        "the mapped field has fields (angular_velocity.x, angular_velocity.y, angular_velocity.z), "
        "it is not a number: map one of them"
    )
    assert error([MappingEntry("/imu/shank", "header.frame_id", "shank_angle_deg")]).endswith(
        "the mapped field is text ('shank'), not a number"
    )
    with pytest.raises(RigMismatch, match=r"file ros\.mcap: the mapping was made for recordings with other topics"):
        foreign_frames(path, "ros.mcap", ChannelMapping(ROS_MAPPING, "0123456789abcdef"))
    assert len(list(foreign_frames(path, "ros.mcap", ChannelMapping(ROS_MAPPING, "x"), allow_other_rig=True))) == 100
    assert len(list(foreign_frames(path, "ros.mcap", ChannelMapping(ROS_MAPPING, "")))) == 100  # any rig
    with pytest.raises(MappingError, match="maps no fields"):
        foreign_frames(path, "ros.mcap", ChannelMapping([], rig))

    empty = write_json(tmp_path / "e.mcap", exo_messages(), empty_topics=("/quiet",))
    with pytest.raises(DataFormatError, match="column '/quiet': the mapped topic /quiet has no messages"):
        foreign_frames(empty, "e.mcap", ChannelMapping([MappingEntry("/quiet", "x", "knee_angle_deg")], ""))
    nothing = write_json(tmp_path / "n.mcap", [], empty_topics=("/quiet",))
    with pytest.raises(DataFormatError, match=r"file n\.mcap: the file holds no messages"):
        foreign_frames(nothing, "n.mcap", ChannelMapping([MappingEntry("/quiet", "x", "knee_angle_deg")], ""))


def test_protobuf_frames_by_their_timestamps(tmp_path: Path) -> None:
    path = write_protobuf(tmp_path / "p.mcap")
    mapping = suggest_mapping(inspect_mcap(path, time_source="header"))
    assert mapping.time_source == "header"
    frames = list(foreign_frames(path, None, mapping))
    assert [f.imu_thigh_gyro_z_dps for f in frames] == pytest.approx([i * RAD_TO_DEG for i in range(30)])
    assert [f.foot_contact for f in frames] == [i < 10 for i in range(30)]
    assert [f.t for f in frames] == pytest.approx([i * 0.02 for i in range(30)])


def test_a_message_without_the_field_holds_and_bad_bytes_are_named(tmp_path: Path) -> None:
    messages = [("/exo", T0 + 10 * MS * i, {"knee": float(i)} if i != 3 else {"ankle": 1.0}) for i in range(6)]
    messages += [("/fast", T0 + 5 * MS * i, {"x": 0.0}) for i in range(12)]
    path = write_json(tmp_path / "j.mcap", sorted(messages, key=lambda m: m[1]))
    entries = [MappingEntry("/exo", "knee", "knee_angle_deg"), MappingEntry("/fast", "x", "shank_angle_deg")]
    knee = [f.knee_angle_deg for f in foreign_frames(path, None, ChannelMapping(entries, ""))]
    assert knee == [0, 0, 1, 1, 2, 2, 2, 2, 4, 4, 5, 5]  # message 3 has no knee: message 2's value is held

    path = tmp_path / "bad.mcap"
    with path.open("wb") as f:
        w = Writer(f)
        w.start(profile="", library="test")
        cid = w.register_channel("/exo", "json", 0)
        for i in range(60):
            w.add_message(cid, T0 + MS * i, b'{"knee": 1}', T0 + MS * i)
        w.add_message(cid, T0 + MS * 60, b"{not json", T0 + MS * 60)
        w.finish()
    with pytest.raises(DataFormatError, match=r"file bad\.mcap, column '/exo': a message could not be decoded"):
        inspect_mcap(path, "bad.mcap")
    assert len(inspect_mcap(path, "bad.mcap", sample_messages=60)) == 1
    # the first 50 messages check the mapping; a bad one after them is met while streaming
    frames = foreign_frames(path, "bad.mcap", ChannelMapping([MappingEntry("/exo", "knee", "knee_angle_deg")], ""))
    with pytest.raises(DataFormatError, match=r"file bad\.mcap: a message could not be decoded"):
        list(frames)


def test_long_arrays_are_cut_and_a_stream_reads_only_the_mapped_leaves(tmp_path: Path) -> None:
    message = {
        "cloud": list(range(100)),
        "name": ["hip", "knee"],
        "position": [1.0, 2.0],
        "arm": {"v": [{"a": 1, "b": "x"}, {"a": 2, "b": "y"}], "blob": None},
    }
    path = write_json(tmp_path / "a.mcap", [("/t", T0, message)])
    paths = [f.path for f in inspect_mcap(path)]
    assert paths == [*(f"cloud[{i}]" for i in range(64)), "position[hip]", "position[knee]", "arm.v[0].a", "arm.v[1].a"]
    assert len([f for f in inspect_mcap(path, max_array=3) if f.path.startswith("cloud")]) == 3
    full = foreign_mcap._flatten(message, 64)
    for wanted in (["position[knee]"], ["arm.v[1].a", "cloud[63]"], ["arm.v[0].b"]):
        pruned = foreign_mcap._flatten(message, 64, foreign_mcap._prefixes(wanted))
        assert pruned == {
            p: v for p, v in full.items() if any(p == w or p.startswith((w + ".", w + "[")) for w in wanted)
        }

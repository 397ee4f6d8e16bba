"""Every wire message round-trips through JSON, and the schema endpoint covers every one of them."""

from __future__ import annotations

import json

import pytest
from pydantic import BaseModel, TypeAdapter, ValidationError

from gaitscope.sessions import schema

EXAMPLES: dict[type[BaseModel], dict] = {
    schema.SubjectCreate: {"code": "AB01", "leg_length_m": 0.9, "mass_kg": 70.0},
    schema.SessionCreate: {"subject_id": 1, "source": {"kind": "replay", "trial_id": 3, "speed": 4.0}},
    schema.SettingsChange: {"torque_gain": 1.2, "actor": "dr-k"},
    schema.SensorFrame: {"seq": 1, "t": 0.01, "foot_angle_deg": 12.0, "heel_strike": True, "sent_ns": 5},
    schema.TorqueCommand: {"seq": 1, "t": 0.01, "torque_Nm": 3.5},
    schema.FoxgloveEvent: {"start_time": {"sec": 1, "nsec": 2}, "end_time": {"sec": 1, "nsec": 2}},
    schema.GPLearningControl: {"action": "rollback", "version": 2, "actor": "dr-k", "reason": "stumbled"},
    schema.GPModelRecord: {
        "t": 12.5,
        "what": "trained",
        "version": 3,
        "steps": [11, 15],
        "span_s": [12.1, 17.4],
        "rmse": {"hip angle": 1.1, "knee velocity": None},
        "fit_s": 0.31,
        "arrays": {"meta": {"shape": [5], "values": [3.0, 12.1, 17.4, 11.0, 15.0]}},
    },
}


@pytest.mark.parametrize("cls", list(EXAMPLES))
def test_round_trip(cls: type[BaseModel]) -> None:
    obj = cls.model_validate(EXAMPLES[cls])
    again = cls.model_validate_json(obj.model_dump_json())
    assert again == obj


def test_every_mcap_channel_class_has_a_schema_and_every_server_message_is_listed() -> None:
    for topic, (name, cls) in schema.MCAP_CHANNELS.items():
        assert topic.startswith("/") and "properties" in cls.model_json_schema()
        assert name.startswith(("gaitscope.", "foxglove."))
    adapter: TypeAdapter[object] = TypeAdapter(schema.ServerMessage)
    kinds = {c.model_fields["type"].default for c in (schema.Hello, schema.StreamBatch, schema.Health,
                                                      schema.EventMessage, schema.SettingsMessage)}  # fmt: skip
    assert kinds == {"hello", "states", "health", "event", "settings"}
    msg = adapter.validate_python(json.loads('{"type": "torque", "seq": 1, "t": 0.5, "torque_Nm": 2.0}'))
    assert isinstance(msg, schema.TorqueCommand)
    assert set(schema.WIRE) >= {cls for _, cls in schema.MCAP_CHANNELS.values()}


def test_unknown_fields_and_bad_values_are_refused() -> None:
    with pytest.raises(ValidationError, match="extra_forbidden"):
        schema.SensorFrame.model_validate({"seq": 1, "t": 0.0, "foot_angel_deg": 3.0})
    with pytest.raises(ValidationError, match="less than or equal to 80"):
        schema.SettingsChange.model_validate({"max_torque_Nm": 81})
    with pytest.raises(ValidationError, match="string_pattern_mismatch"):
        schema.SubjectCreate.model_validate({"code": "../x", "leg_length_m": 0.9, "mass_kg": 70})
    for body in ({"action": "rollback"}, {"action": "freeze", "version": 1}):
        with pytest.raises(ValidationError, match="a rollback names the version to reinstall"):
            schema.GPLearningControl.model_validate(body)


# --- the sensor frame, version 2 -----------------------------------------------------------------

#: A frame as version 1 devices sent it and version 1 recordings hold it: no ``version`` field.
V1_FRAME = (
    '{"type": "frame", "seq": 7, "t": 12.5, "foot_angle_deg": 12.25, "foot_vel_dps": -103.5, "shank_angle_deg": 5.5,'
    ' "shank_vel_dps": 87.0, "heel_forward_m": 0.125, "heel_up_m": -0.0625, "thigh_angle_deg": 20.0,'
    ' "heel_strike": false, "sent_ns": 1712345678901234567}'
)
FRAME_META = {"type", "version", "seq", "t", "sent_ns"}


def test_a_version_1_frame_reads_as_version_2_with_the_same_values() -> None:
    frame = schema.SensorFrame.model_validate_json(V1_FRAME)
    assert frame.version == 2 == schema.SENSOR_FRAME_VERSION
    assert frame.model_dump(exclude_none=True, exclude={"version"}) == json.loads(V1_FRAME)
    declared = schema.SensorFrame.model_validate_json(V1_FRAME.replace('"seq"', '"version": 1, "seq"'))
    assert declared == frame  # a frame that says it is version 1 is upgraded on read
    assert json.loads(frame.model_dump_json())["version"] == 2  # and written back as version 2
    with pytest.raises(ValidationError, match="literal_error"):
        schema.SensorFrame.model_validate_json(V1_FRAME.replace('"seq"', '"version": 3, "seq"'))


def test_every_channel_is_an_optional_field_with_its_unit_and_bounds() -> None:
    fields = schema.SensorFrame.model_fields
    assert set(schema.CHANNELS) == set(fields) - FRAME_META
    for name, channel in schema.CHANNELS.items():
        assert fields[name].default is None and fields[name].description
        flag = channel.unit == "bool"
        assert (fields[name].annotation == (bool | None)) is flag, name
        assert (name in schema.SENSOR_LIMITS) is not flag, name
        if not flag:
            assert channel.unit in (fields[name].description or ""), name
    assert {c.group for c in schema.CHANNELS.values()} == {
        "segment", "heel", "joint", "imu", "foot", "event", "device", "treadmill", "step", "com"
    }  # fmt: skip
    assert sum(c.group == "imu" for c in schema.CHANNELS.values()) == 6 * len(schema.IMU_SEGMENTS)
    for name in ("foot_angle_deg", "foot_vel_dps", "shank_angle_deg", "shank_vel_dps", "heel_forward_m", "heel_up_m"):
        assert name in schema.REPLAY_SIGNALS and name in schema.CHANNELS  # version 1 names kept
    limits = schema.SENSOR_LIMITS
    assert limits["foot_force_N"] == (0.0, 5000.0) and limits["imu_pelvis_accel_z_m_s2"] == (-157.0, 157.0)
    assert limits["imu_foot_contra_gyro_x_dps"] == (-4000.0, 4000.0) and limits["belt_speed_m_s"] == (0.0, 5.0)
    assert limits["com_forward_m"] == (-3.0, 3.0) and limits["thigh_angle_deg"] == (-180.0, 180.0)


@pytest.mark.parametrize("extra", [0, 40], ids=["sparse", "dense"])
def test_implausible_values_of_any_channel_are_treated_as_missing(extra: int) -> None:
    bad = {"foot_force_N": -1.0, "imu_thigh_accel_y_m_s2": 200.0, "motor_current_A": float("nan")}
    filler = {n: 0.5 for n in [n for n in schema.SENSOR_LIMITS if n not in bad][:extra]}
    frame = schema.SensorFrame.model_validate({"seq": 0, "t": 0.0, **filler, **bad, "foot_contact": True})
    clean, n = frame.plausible()
    assert n == 3 and all(getattr(clean, k) is None for k in bad)
    assert clean.foot_contact is True and all(getattr(clean, k) == 0.5 for k in filler)
    edge = schema.SensorFrame(seq=0, t=0.0, foot_force_N=0.0, imu_pelvis_gyro_z_dps=-4000.0)
    assert edge.plausible() == (edge, 0)  # the bounds themselves are plausible


def test_missing_channels_names_what_a_frame_or_a_source_lacks_in_the_order_asked() -> None:
    frame = schema.SensorFrame.model_validate_json(V1_FRAME)
    need = ["hip_angle_deg", "thigh_angle_deg", "foot_contact", "heel_strike", "com_forward_m"]
    assert schema.missing_channels(need, frame) == ["hip_angle_deg", "foot_contact", "com_forward_m"]
    assert schema.missing_channels(need, ["com_forward_m", "hip_angle_deg"]) == [
        "thigh_angle_deg", "foot_contact", "heel_strike"
    ]  # fmt: skip
    assert schema.missing_channels([], frame) == [] and schema.missing_channels(need, schema.CHANNELS) == []
    with pytest.raises(KeyError, match="hip_angel_deg"):
        schema.missing_channels(["hip_angel_deg"], schema.CHANNELS)


# --- a device's declared rate and frame size (issue 21) ---------------------------------------------


def test_a_device_declares_at_most_1000_hz_and_an_older_stored_session_reads_as_the_limit() -> None:
    assert schema.DeviceSource(rate_hz=1000).rate_hz == schema.MAX_DEVICE_RATE_HZ == 1000
    with pytest.raises(ValidationError, match="less than or equal to 1000"):
        schema.DeviceSource(rate_hz=1000.5)
    with pytest.raises(ValidationError, match="less than or equal to 1000"):  # a request body
        schema.SessionCreate.model_validate({"subject_id": 1, "source": {"kind": "device", "rate_hz": 2000}})
    stored = TypeAdapter(schema.SourceSpec).validate_json(
        '{"kind": "device", "rate_hz": 2000}', context={"stored": True}
    )
    assert isinstance(stored, schema.DeviceSource) and stored.rate_hz == 1000
    assert "at most 1000" in schema.DeviceSource.model_json_schema()["properties"]["rate_hz"]["description"]


def test_the_frame_size_limit_holds_every_channel_four_times_over_and_the_key_limit_every_field() -> None:
    every = {"type": "frame", "version": 2, "seq": schema.INT64_MAX, "t": -1.2345678901234567e-308}
    every |= {name: False if ch.unit == "bool" else -1.2345678901234567e-308 for name, ch in schema.CHANNELS.items()}
    every["sent_ns"] = schema.INT64_MAX
    text = json.dumps(every, indent=2)  # pretty-printed, the longest numbers
    assert 3_000 < len(json.dumps(every)) <= schema.MAX_FRAME_BYTES / 4 and len(text) < schema.MAX_FRAME_BYTES / 3
    assert schema.MAX_FRAME_BYTES == 16 * 1024
    assert text.count(":") == len(every) == schema.MAX_FRAME_KEYS
    schema.SensorFrame.model_validate_json(text)

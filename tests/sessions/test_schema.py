"""Every wire message round-trips through JSON, and the schema endpoint covers every one of them."""

from __future__ import annotations

import json

import pytest
from pydantic import BaseModel, TypeAdapter, ValidationError

from server.api import _WIRE
from sessions import schema

EXAMPLES: dict[type[BaseModel], dict] = {
    schema.SubjectCreate: {"code": "AB01", "leg_length_m": 0.9, "mass_kg": 70.0},
    schema.SessionCreate: {"subject_id": 1, "source": {"kind": "replay", "trial_id": 3, "speed": 4.0}},
    schema.SettingsChange: {"torque_gain": 1.2, "actor": "dr-k"},
    schema.SensorFrame: {"seq": 1, "t": 0.01, "foot_angle_deg": 12.0, "heel_strike": True, "sent_ns": 5},
    schema.TorqueCommand: {"seq": 1, "t": 0.01, "torque_Nm": 3.5},
    schema.FoxgloveEvent: {"start_time": {"sec": 1, "nsec": 2}, "end_time": {"sec": 1, "nsec": 2}},
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
    assert set(_WIRE) >= {cls for _, cls in schema.MCAP_CHANNELS.values()}


def test_unknown_fields_and_bad_values_are_refused() -> None:
    with pytest.raises(ValidationError, match="extra_forbidden"):
        schema.SensorFrame.model_validate({"seq": 1, "t": 0.0, "foot_angel_deg": 3.0})
    with pytest.raises(ValidationError, match="less than or equal to 80"):
        schema.SettingsChange.model_validate({"max_torque_Nm": 81})
    with pytest.raises(ValidationError, match="string_pattern_mismatch"):
        schema.SubjectCreate.model_validate({"code": "../x", "leg_length_m": 0.9, "mass_kg": 70})

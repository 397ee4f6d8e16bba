"""The sensor-to-estimate path's hot-path serialisation reads back as the schema's models."""

from __future__ import annotations

import math

import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from gaitscope.sessions.estimation import frame_json, torque_json
from gaitscope.sessions.schema import SensorFrame, TorqueCommand


@pytest.mark.parametrize(
    "fields",
    [
        {"seq": 0, "t": 12.5},
        {"seq": 7, "t": 1e9, "foot_angle_deg": -3.25, "heel_strike": True, "sent_ns": 1_700_000_000_000_000_000},
        {"seq": 3, "t": 0.005, "shank_vel_dps": 1e-300, "belt_speed_m_s": 1.2, "thigh_angle_deg": 0.1},
    ],
)
@pytest.mark.parametrize("t", [0.0, 0.1 + 0.2, 1234.567890123, 5e-324])
def test_a_recorded_sensor_frame_is_the_frame_at_session_time(fields: dict[str, object], t: float) -> None:
    frame = SensorFrame.model_validate(fields)
    back = SensorFrame.model_validate_json(frame_json(frame, t))
    assert back == frame.model_copy(update={"t": t})
    assert back.t == t and math.copysign(1.0, back.t) == math.copysign(1.0, t)


@given(
    seq=st.integers(min_value=0, max_value=2**63 - 1),
    t=st.floats(allow_nan=True, allow_infinity=True),
    torque=st.floats(allow_nan=True, allow_infinity=True),
)
@example(seq=0, t=math.inf, torque=-0.0)  # found by hypothesis: -0.0 is sent as 0.0 whatever the time
def test_a_torque_command_is_the_model_as_json(seq: int, t: float, torque: float) -> None:
    text = torque_json(seq, t, torque)
    model = TorqueCommand(seq=seq, t=t, torque_Nm=torque + 0.0)  # -0.0 is sent as 0.0
    if math.isfinite(t) and math.isfinite(torque):
        assert TorqueCommand.model_validate_json(text) == model
    else:  # never sent (the torque is clamped, session time finite): whatever the model says, of +0.0 for -0.0
        assert text == TorqueCommand(seq=seq, t=t, torque_Nm=torque + 0.0).model_dump_json()
    assert not text.endswith('"torque_Nm":-0.0}')


def test_a_device_sending_raw_imus_only_gets_the_derived_angles_in_its_gait_state() -> None:
    """The leg view and the angle plots read the gait state's angles: from an IMU-only device they are
    the IMU front ends' (issue #10), close to the true ones once the filters have settled."""
    import numpy as np

    from gaitscope.sessions.estimation import FrameEstimator
    from gaitscope.sessions.formats.models import default_model_path, load_model
    from gaitscope.sessions.formats.replay_io import RAW_IMUS
    from gaitscope.sessions.live.sources import frames_from_table
    from gaitscope.sessions.schema import SessionSettings
    from gaitscope.sessions.synth.trials import sensor_trial

    sensors, leg, mass = sensor_trial([(1.1, 0.0, 12)], rate_hz=100.0)
    raw = sensors[["time_s", *RAW_IMUS["foot"], *RAW_IMUS["shank"], *RAW_IMUS["thigh"]]]
    model, _ = load_model(default_model_path())
    est = FrameEstimator(model, leg, mass, SessionSettings(), 0.01, soft_start=False)
    states = [est.step(f, 0) for f in frames_from_table(raw)]
    late = slice(len(states) // 2, None)
    # against the device's own angle channels: the thigh's is clean, the foot's has 1 deg of noise and the
    # shank's 7 (seed 000's sensor noise), on top of the front end's own error (docs/results.md)
    for name, limit in (("foot_angle_deg", 8.0), ("shank_angle_deg", 15.0), ("thigh_angle_deg", 6.0)):
        got = np.array([getattr(s, name) for s in states[late]], dtype=float)
        truth = sensors[name].to_numpy()[late]
        assert np.isfinite(got).all(), name
        assert np.sqrt(np.mean((got - truth) ** 2)) < limit, name

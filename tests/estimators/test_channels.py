"""The channel table is the only source of channel names and bounds: the wire schema is made from it, every
estimator names its inputs from it, and no other module keeps a range of its own."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from gaitscope.estimators import (
    channels,
    detector,
    fingerprint,
    gp_ekf_estimator,
    heel_strike,
    intent_estimator,
    phase_ekf_estimator,
    pipeline,
)
from gaitscope.estimators.channels import CHANNELS, GROUPS, LIMITS, positions, span, symmetric_bound
from gaitscope.estimators.protocol import ANGLE_CHANNELS, HEEL_STRIKE, SENSOR_CHANNELS, input_names
from gaitscope.sessions import schema
from gaitscope.sessions.formats.models import default_model_path, load_model
from gaitscope.sessions.registry import DECLARED, ESTIMATORS, StackContext

ROOT = Path(__file__).resolve().parents[2]
#: The suffix each unit's channel names end in (a flag's name has none).
SUFFIX = {"deg": "_deg", "deg/s": "_dps", "m": "_m", "m/s": "_m_s", "m/s^2": "_m_s2", "N": "_N", "A": "_A",
          "N m": "_Nm"}  # fmt: skip
FRAME_META = {"type", "version", "seq", "t", "sent_ns"}


def test_every_channel_has_a_unit_its_name_ends_in_a_group_and_a_range_unless_a_flag() -> None:
    assert len(CHANNELS) == 77 and list(CHANNELS)[:8] == [
        "foot_angle_deg", "foot_vel_dps", "shank_angle_deg", "shank_vel_dps", "heel_forward_m", "heel_up_m",
        "thigh_angle_deg", "thigh_vel_dps",
    ]  # fmt: skip  # version 1's channels first, in their order
    for name, ch in CHANNELS.items():
        assert ch.group in GROUPS and ch.description, name
        if ch.unit == "bool":
            assert ch.limits is None and not name.endswith(tuple(SUFFIX.values())), name
        else:
            assert name.endswith(SUFFIX[ch.unit]), name
            assert ch.limits is not None and ch.limits[0] < ch.limits[1], name
            assert LIMITS[name] == ch.limits
    assert set(LIMITS) == {n for n, c in CHANNELS.items() if c.unit != "bool"}
    assert {c.group for c in CHANNELS.values()} == set(GROUPS)
    assert sum(c.group == "imu" for c in CHANNELS.values()) == 6 * len(channels.IMU_SEGMENTS)


def test_the_schema_takes_its_channels_and_bounds_from_the_table() -> None:
    assert schema.CHANNELS is CHANNELS and schema.SENSOR_LIMITS is LIMITS and schema.Channel is channels.Channel
    assert schema.IMU_SEGMENTS is channels.IMU_SEGMENTS
    assert schema.REPLAY_SIGNALS is SENSOR_CHANNELS and schema.REPLAY_HEEL_STRIKE == HEEL_STRIKE == "heel_strike"
    assert schema.SENSOR_LIMITS == {n: c.limits for n, c in CHANNELS.items() if c.limits is not None}


def test_the_sensor_frame_fields_are_the_table_s_channels_in_its_order() -> None:
    fields = schema.SensorFrame.model_fields
    assert [n for n in fields if n not in FRAME_META] == list(CHANNELS)
    assert list(fields)[:4] == ["type", "version", "seq", "t"] and list(fields)[-1] == "sent_ns"
    for name, ch in CHANNELS.items():
        f = fields[name]
        assert f.default is None and f.annotation == (bool | None if ch.unit == "bool" else float | None), name
        assert f.description == (ch.description if ch.unit == "bool" else f"{ch.description} ({ch.unit})")
    frame = schema.SensorFrame(seq=0, t=0.0, imu_foot_contra_accel_z_m_s2=200.0, heel_up_m=-3.0)
    assert frame.plausible()[1] == 1  # the table's range: 200 m/s^2 is beyond 16 g, -3 m is the bound itself


@pytest.fixture(scope="module")
def built() -> dict[str, object]:
    model, _ = load_model(default_model_path())
    ctx = StackContext(model, 0.9, 70.0, 0.01, fingerprint=(1.0, -0.5, 0.2))
    return {name: make(ctx) for name, make in ESTIMATORS.items()}


def test_every_estimator_reads_table_channels_and_writes_them_in_their_units(built: dict[str, object]) -> None:
    assert list(built) == list(DECLARED)
    for name, est in built.items():
        read = input_names(est)  # type: ignore[arg-type]
        assert read and set(read) <= set(CHANNELS), (name, set(read) - set(CHANNELS))
        assert len(set(read)) == len(read), name
        for out, unit in est.outputs:  # type: ignore[attr-defined]
            if out in CHANNELS:  # a derived channel (IMU front ends, CoM kinematics, the detector's heel strike)
                assert unit == CHANNELS[out].unit, (name, out, unit)
    assert set(SENSOR_CHANNELS) <= set(CHANNELS) and HEEL_STRIKE in CHANNELS
    for angle, vel in ANGLE_CHANNELS.items():
        a, v = CHANNELS[angle], CHANNELS[vel]
        assert (a.unit, v.unit, a.group, v.group) == ("deg", "deg/s", "segment", "segment")
        assert a.description.split(" angle")[0] == v.description.split(" angular velocity")[0]  # one segment


def test_the_estimators_bounds_are_the_table_s() -> None:
    assert pipeline.CHANNEL_LIMITS == tuple(LIMITS[n] for n in SENSOR_CHANNELS)
    assert pipeline.PipelineConfig().channel_limits == pipeline.CHANNEL_LIMITS
    angles = ("hip_angle_deg", "knee_angle_deg", "ankle_angle_deg", "foot_angle_deg")
    assert {LIMITS[n] for n in angles} == {(-gp_ekf_estimator._ANGLE_LIMIT, gp_ekf_estimator._ANGLE_LIMIT)}
    assert LIMITS["foot_vel_dps"] == (-gp_ekf_estimator._VELOCITY_LIMIT, gp_ekf_estimator._VELOCITY_LIMIT)
    # the intent estimator's own limits only drop the absurd: they admit every plausible value of the table
    m = intent_estimator
    for name in (*m.COM_CHANNELS, *m.COM_LATERAL):
        assert -m._MAX_COM < LIMITS[name][0] and LIMITS[name][1] < m._MAX_COM, name
    for name in ("foot_force_N", "foot_force_contra_N"):
        assert -m._MAX_FORCE_N < LIMITS[name][0] and LIMITS[name][1] < m._MAX_FORCE_N, name
    hips = LIMITS["hip_angle_deg"][1] - LIMITS["hip_angle_contra_deg"][0]
    assert hips <= m._MAX_HIP_DEG and LIMITS["step_length_m"][1] < m._MAX_STEP_M


def test_no_other_module_keeps_a_channel_range_of_its_own() -> None:
    pairs = {f"({lo!r}, {hi!r})" for lo, hi in LIMITS.values()}
    literal = re.compile("|".join(re.escape(p) for p in sorted(pairs)))
    found = []
    for folder in ("estimators", "sessions", "server"):
        for path in (ROOT / folder).rglob("*.py"):
            if path == ROOT / "estimators" / "channels.py":
                continue
            found += [f"{path.relative_to(ROOT)}:{i}" for i, line in enumerate(path.read_text().splitlines(), 1)
                      if literal.search(line)]  # fmt: skip
    assert (ROOT / "estimators" / "channels.py").read_text().count("(-180.0, 180.0)") == 1
    assert found == []


def test_estimators_find_their_channels_in_z_by_name() -> None:
    """The named indices are where each estimator declares the channel (as the magic numbers were)."""
    order = input_names
    intent = order(intent_estimator.IntentEstimator)  # type: ignore[arg-type]
    assert [intent[i] for i in intent_estimator._COM] == [
        "com_forward_m", "com_lateral_m", "com_up_m", "com_forward_vel_m_s", "com_lateral_vel_m_s", "com_up_vel_m_s"
    ]  # fmt: skip
    m = intent_estimator
    assert (m._HIP, m._HIP_C, m._FORCE, m._FORCE_C, m._STEP, m._CONTACT, m._CONTACT_C, m._CURRENT) == (
        4, 5, 6, 7, 8, 11, 12, 13
    )  # fmt: skip
    p = phase_ekf_estimator
    assert (p._FOOT, p._FOOT_VEL, p._SHANK_VEL, p._HS, p._SENSORS) == (0, 1, 3, 6, slice(0, 6))
    g = gp_ekf_estimator
    assert (g._HIP, g._KNEE, g._ANKLE, g._HS, g._FOOT, g._FOOT_VEL) == (0, 1, 2, 3, 4, 5)
    assert (detector._ANGLE, detector._VEL, detector._HEEL) == (0, 1, slice(2, 4))
    assert (heel_strike._HS, heel_strike._SENSORS) == (0, slice(1, 5))
    assert (fingerprint._THIGH, fingerprint._THIGH_VEL) == (0, 1)


def test_positions_span_and_symmetric_bound_refuse_what_the_table_does_not_hold() -> None:
    order = ("heel_strike", "foot_angle_deg", "foot_vel_dps")
    assert positions(order, "foot_vel_dps", "heel_strike") == (2, 0)
    assert span(order, "foot_angle_deg", "foot_vel_dps") == slice(1, 3)
    with pytest.raises(KeyError, match="foot_angel_deg"):
        positions(order, "foot_angel_deg")  # a typo is not a channel
    with pytest.raises(ValueError):
        positions(order, "shank_angle_deg")  # a channel the order lacks
    with pytest.raises(ValueError, match="consecutive"):
        span(order, "heel_strike", "foot_vel_dps")
    with pytest.raises(ValueError, match="consecutive"):
        span(order, "foot_vel_dps", "foot_angle_deg")
    assert symmetric_bound("thigh_angle_deg", "ankle_angle_contra_deg") == 180.0
    with pytest.raises(ValueError, match="symmetric"):
        symmetric_bound("foot_force_N")  # 0 .. 5000 N
    with pytest.raises(ValueError, match="symmetric"):
        symmetric_bound("foot_angle_deg", "foot_vel_dps")  # two ranges
    with pytest.raises(KeyError):
        symmetric_bound("heel_strike")  # a flag has no range

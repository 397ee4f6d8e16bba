"""Property: whatever the sensors send, the torque is a finite number within [0, max torque].

Drives the estimator stack (the pipeline replay runs, and the frame estimator the live path and
re-runs use) with arbitrary floats: NaN, infinities, huge and denormal values, arbitrary time steps;
and a session's stack with estimators that break (raise, return NaN, diverge), the primary among them.
The live websocket and the replay command are driven the same way in ``test_live_faults.py`` and
``test_replay_faults.py``.
"""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gaitscope.estimators.pipeline import GaitStatePipeline, PipelineConfig, TrainedModel
from gaitscope.sessions.estimation import FrameEstimator, FrameRefused, torque_json
from gaitscope.sessions.live.runtime import safe_torque
from gaitscope.sessions.live.sources import frames_from_table
from gaitscope.sessions.schema import SENSOR_LIMITS, SensorFrame, SessionSettings
from gaitscope.sessions.synth.trials import sensor_trial
from tests.device_tokens import device_path
from tests.estimator_doubles import Scripted

ANY_FLOAT = st.floats(allow_nan=True, allow_infinity=True, allow_subnormal=True)
CHANNEL = st.one_of(ANY_FLOAT, st.floats(-200.0, 200.0), st.just(math.nan))
MAX_TORQUE = 25.0

SAFE = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _finite_state(values: list[float]) -> bool:
    return all(math.isfinite(v) for v in values)


@SAFE
@given(
    samples=st.lists(
        st.tuples(
            st.one_of(st.floats(5e-324, 1e12), st.floats(0.001, 0.02)), st.lists(CHANNEL, min_size=6, max_size=6)
        ),
        min_size=1,
        max_size=40,
    ),
    heel_strikes=st.lists(st.sampled_from([None, True, False]), min_size=40, max_size=40),
)
def test_pipeline_torque_is_finite_and_bounded(
    small_model: TrainedModel, samples: list[tuple[float, list[float]]], heel_strikes: list[bool | None]
) -> None:
    pipe = GaitStatePipeline(small_model, PipelineConfig(max_torque=MAX_TORQUE, torque_gain=3.0), sample_period=0.005)
    t = 0.0
    for (dt, raw), hs in zip(samples, heel_strikes, strict=False):
        t_next = t + dt
        if not t_next > t:
            continue
        t = t_next
        e = pipe.step(t, np.array(raw), hs)
        assert 0.0 <= e.torque_Nm <= MAX_TORQUE
        assert _finite_state([e.phase, e.phase_rate, e.stride_length_m, e.incline_deg, e.tbe_phase])


@SAFE
@given(
    frames=st.lists(
        st.fixed_dictionaries(
            {"t": st.one_of(st.floats(-1e12, 1e12, allow_subnormal=True), st.floats(0.0, 5.0))},
            optional={name: CHANNEL for name in SENSOR_LIMITS},
        ),
        min_size=1,
        max_size=40,
    )
)
def test_frame_estimator_torque_is_finite_and_bounded(small_model: TrainedModel, frames: list[dict]) -> None:
    est = FrameEstimator(small_model, 0.9, 75.0, SessionSettings(torque_gain=3.0, max_torque_Nm=MAX_TORQUE))
    for k, fields in enumerate(frames):
        frame = SensorFrame.model_validate({"seq": k, **fields})
        try:
            state = est.step(frame, 0)
        except FrameRefused:
            continue
        assert 0.0 <= state.torque_Nm <= MAX_TORQUE
        assert _finite_state([state.t, state.phase, state.phase_rate, state.stride_length_m, state.incline_deg])
        assert state.t >= 0.0 and math.isfinite(state.foot_pred_deg)
        state.model_dump_json()  # serialisable, no NaN for JSON to turn into null


def _frames(channels: tuple[str, ...], max_size: int) -> st.SearchStrategy[list[dict]]:
    """Frames with any time (absurd ones among them), any subset of ``channels`` at any value, heel strikes."""
    return st.lists(
        st.fixed_dictionaries(
            {"t": st.one_of(st.floats(-1e12, 1e12, allow_subnormal=True), st.floats(0.0, 5.0))},
            optional={name: CHANNEL for name in channels} | {"heel_strike": st.booleans()},
        ),
        min_size=1,
        max_size=max_size,
    )


FRAMES = _frames(("foot_angle_deg", "foot_vel_dps", "shank_angle_deg", "shank_vel_dps"), 40)
BREAKS = st.lists(
    st.tuples(st.sampled_from(["raise_after", "nan_after", "diverge_after"]), st.integers(0, 40)), max_size=3
)


@SAFE
@given(
    frames=FRAMES,
    breaks=BREAKS,
    primary=st.sampled_from(["phase_ekf", "tbe", "b0", "b1"]),
    switch=st.tuples(st.integers(0, 40), st.sampled_from(["phase_ekf", "tbe", "hs_backup", "b0", "b1", "b2"])),
    blend_s=st.sampled_from([0.0, 0.005, 0.5]),
)
def test_a_stack_with_broken_estimators_keeps_the_torque_finite_and_bounded(
    small_model: TrainedModel,
    frames: list[dict],
    breaks: list[tuple[str, int]],
    primary: str,
    switch: tuple[int, str],
    blend_s: float,
) -> None:
    """Estimators that raise, return NaN or diverge (the primary among them), arbitrary frames and
    primary switches: the torque stays a finite number within the bound, the gait state finite."""
    extra = [Scripted(f"b{i}", shift=0.3 * i, **{how: n}) for i, (how, n) in enumerate(breaks)]
    names = {"phase_ekf", "tbe", "hs_detector", "hs_backup"} | {e.name for e in extra}
    settings = SessionSettings(
        torque_gain=3.0, max_torque_Nm=MAX_TORQUE, primary=primary if primary in names else "phase_ekf"
    )
    est = FrameEstimator(small_model, 0.9, 75.0, settings, 0.005, extra=extra, blend_s=blend_s)
    for k, fields in enumerate(frames):
        if k == switch[0]:
            try:
                est.retune(settings.model_copy(update={"primary": switch[1]}))
            except ValueError:
                pass  # not in the stack, or failed: refused, nothing changes
        frame = SensorFrame.model_validate({"seq": k, **fields})
        try:
            state = est.step(frame, 0)
        except FrameRefused:
            continue
        assert 0.0 <= state.torque_Nm <= MAX_TORQUE
        assert _finite_state([state.phase, state.phase_rate, state.stride_length_m, state.incline_deg, state.tbe_phase])
        state.model_dump_json()
    assert set(est.stack.failed) <= {e.name for e in extra}  # only the broken ones ever fail


GP_FRAMES = _frames(("hip_angle_deg", "knee_angle_deg", "ankle_angle_deg", "foot_angle_deg"), 60)


@SAFE
@given(frames=GP_FRAMES, switch=st.tuples(st.integers(0, 60), st.sampled_from(["gp_ekf", "tbe"])))
def test_the_gp_ekf_as_primary_keeps_the_torque_finite_and_bounded(
    small_model: TrainedModel, frames: list[dict], switch: tuple[int, str]
) -> None:
    """The GP-EKF drives the torque with its own control surface (``gaitscope.sessions.stack``): whatever the joint
    encoders and heel strikes say, and across primary switches, the command stays within the bound."""
    settings = SessionSettings(
        torque_gain=3.0, max_torque_Nm=MAX_TORQUE, primary="gp_ekf", estimators=["tbe", "gp_ekf"]
    )
    est = FrameEstimator(small_model, 0.9, 75.0, settings, 0.005, soft_start=False)
    for k, fields in enumerate(frames):
        if k == switch[0]:
            est.retune(settings.model_copy(update={"primary": switch[1]}))
        frame = SensorFrame.model_validate({"seq": k, **fields})
        try:
            state = est.step(frame, 0)
        except FrameRefused:
            continue
        assert 0.0 <= state.torque_Nm <= MAX_TORQUE
        assert _finite_state([state.phase, state.phase_rate, state.tbe_phase])
        state.model_dump_json()
    assert est.stack.failed == {}


def test_a_huge_velocity_does_not_poison_the_filter(small_model: TrainedModel) -> None:
    """Reproduces the reported failure: one frame with foot_vel_dps = 1e50 made every later torque null."""
    est = FrameEstimator(small_model, 0.9, 75.0, SessionSettings(), 0.01, soft_start=False)
    torques = []
    for k in range(300):
        bad = {"foot_vel_dps": 1e50} if k == 10 else {}
        angle = 20.0 * math.sin(2 * math.pi * k / 100)
        frame = SensorFrame.model_validate({"seq": k, "t": k * 0.01, "foot_angle_deg": angle, **bad})
        torques.append(est.step(frame, 0).torque_Nm)
    assert all(math.isfinite(x) for x in torques) and max(torques[20:]) > 0.0
    assert est.implausible == 1


def test_a_time_jump_restarts_instead_of_blowing_up(small_model: TrainedModel) -> None:
    """Reproduces the reported failure: one frame at t = 1e10 made every later torque null."""
    est = FrameEstimator(small_model, 0.9, 75.0, SessionSettings(), 0.01, soft_start=False)
    ts = [k * 0.01 for k in range(100)] + [1e10] + [1.0 + k * 0.01 for k in range(200)]
    states = [est.step(SensorFrame(seq=k, t=t, foot_angle_deg=10.0 * math.sin(t * 6.0)), 0) for k, t in enumerate(ts)]
    assert all(math.isfinite(s.torque_Nm) and math.isfinite(s.phase) for s in states)
    times = [s.t for s in states]
    assert all(b > a for a, b in itertools.pairwise(times)) and times[-1] < 10.0  # resynchronised
    assert any("resynchronised" in n for n in est.notes)


def test_a_diverged_filter_is_reset_with_zero_torque(small_model: TrainedModel) -> None:
    pipe = GaitStatePipeline(small_model, PipelineConfig(), sample_period=0.01)
    pipe.step(0.0, np.full(6, np.nan))
    pipe.ekf.x[1] = math.nan  # as if a numerical fault had happened inside the filter
    e = pipe.step(0.01, np.full(6, np.nan))
    assert e.fault == "diverged" and e.torque_Nm == 0.0 and math.isfinite(e.phase_rate)
    assert np.all(np.isfinite(pipe.ekf.P)) and pipe.resets == 1
    assert pipe.step(0.02, np.full(6, np.nan)).fault == ""


def test_a_zero_torque_is_never_negative_zero_on_the_wire(client: TestClient) -> None:
    """The soft start's first sample is 0 N m times the profile, which is -0.0 where the profile is negative
    (issue #21): the device is sent 0.0, never -0.0."""
    assert math.copysign(1.0, safe_torque(-0.0, 30.0)) == 1.0
    assert math.copysign(1.0, safe_torque(-1e-300, 30.0)) == 1.0
    assert torque_json(3, 0.5, -0.0) == '{"type":"torque","seq":3,"t":0.5,"torque_Nm":0.0}'
    subject = client.post("/api/subjects", json={"code": "Z0", "leg_length_m": 0.9, "mass_kg": 70}).json()["id"]
    session = client.post("/api/sessions", json={"subject_id": subject, "source": {"kind": "device"}}).json()["id"]
    sensors, _, _ = sensor_trial([(1.0, 0.0, 2)], rate_hz=100.0)
    with client.websocket_connect(device_path(client, session)) as ws:
        for frame in frames_from_table(sensors)[:40]:
            ws.send_text(frame.model_dump_json(exclude_none=True))
            reply = ws.receive_text()
            assert '"torque_Nm":-0.0' not in reply, reply
            assert math.copysign(1.0, json.loads(reply)["torque_Nm"]) == 1.0

"""Virtual cohort: determinism, layout, realism checks, sensor simulation and resampling."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from gaitscope.sessions import schema as s
from gaitscope.sessions.synth.cohort import (
    CohortSpec,
    SensorNoise,
    cohort_subject_metadata,
    generate_cohort,
    generate_walk,
    make_subjects,
    resample_walk,
    simulate_sensors,
)
from gaitscope.sessions.synth.sensors import drop_duplicate_instants

SPEC = CohortSpec(n_subjects=2, speeds_m_s=(0.8, 1.2), inclines_deg=(-10.0, 10.0), strides_per_condition=5)
N = SPEC.samples_per_stride
SIGNALS = (
    s.THIGH_ANGLE,
    s.SHANK_ANGLE,
    s.FOOT_ANGLE,
    s.HIP_ANGLE,
    s.KNEE_ANGLE,
    s.ANKLE_ANGLE,
    s.HIP_ANGLE_CONTRA,
    s.HEEL_FORWARD,
    s.HEEL_UP,
    s.ANKLE_MOMENT,
    *s.COM_POSITION,
    *s.COM_VELOCITY,
)
#: Clean columns added with schema version 2 of the sensor frame (tests/sessions/synth/test_body.py).
V2_COLUMNS = (
    s.THIGH_ANGLE_CONTRA,
    s.SHANK_ANGLE_CONTRA,
    s.FOOT_ANGLE_CONTRA,
    s.KNEE_ANGLE_CONTRA,
    s.ANKLE_ANGLE_CONTRA,
    s.PELVIS_ANGLE,
    s.VERTICAL_GRF,
    s.VERTICAL_GRF_CONTRA,
    *s.COM_STANCE_POSITION,
    *(c for pair in s.IMU_POINT_ACCELERATION.values() for c in pair),
    s.STEP_LENGTH_CONTRA,
)
FLOATS = (
    *SIGNALS,
    *V2_COLUMNS,
    s.PHASE_IPSI,
    s.TIME_S,
    s.HEEL_STRIKE,
    s.TOE_OFF,
    s.HEEL_STRIKE_CONTRA,
    s.STEP_LENGTH,
    s.PHASE_RATE,
    s.STRIDE_LENGTH,
    s.INCLINE,
    s.SPEED,
)
TEXT = (s.SUBJECT, s.SUBJECT_METADATA, s.TASK, s.TASK_ID, s.TASK_INFO)


@pytest.fixture(scope="module")
def cohort() -> pd.DataFrame:
    return generate_cohort(SPEC)


@pytest.fixture(scope="module")
def long_walk() -> pd.DataFrame:
    return generate_walk(make_subjects(SPEC)[0], [(1.0, 0.0, 200)], np.random.default_rng(3))


def _deg(x: pd.Series) -> np.ndarray:
    return np.degrees(x.to_numpy(np.float64))


# --- subjects and determinism --------------------------------------------------------------------
def test_subjects_follow_the_anthropometric_rules() -> None:
    subjects = make_subjects(CohortSpec())
    assert [x.code for x in subjects] == [f"VC{i:02d}" for i in range(1, 11)]
    for x in subjects:
        assert 0.78 <= x.leg_length_m <= 0.98
        assert x.height_m == pytest.approx(x.leg_length_m / 0.530, abs=1e-3)
        leg = x.thigh_length_m + x.shank_length_m + x.ankle_height_m
        assert leg == pytest.approx(x.leg_length_m, abs=1e-3)
        assert x.mass_kg == pytest.approx(x.bmi * x.height_m**2, abs=0.05)
    assert len({x.leg_length_m for x in subjects}) == 10
    assert make_subjects(CohortSpec(n_subjects=3)) == subjects[:3]  # subject i depends on (seed, i) only


def test_same_spec_same_frame_other_seed_other_frame(cohort: pd.DataFrame) -> None:
    pd.testing.assert_frame_equal(generate_cohort(SPEC), cohort)
    other = generate_cohort(CohortSpec(**{**SPEC.__dict__, "seed": SPEC.seed + 1}))
    assert other.shape == cohort.shape
    assert not np.allclose(other[s.FOOT_ANGLE], cohort[s.FOOT_ANGLE])


def test_a_subset_of_the_spec_reproduces_its_rows(cohort: pd.DataFrame) -> None:
    one = CohortSpec(n_subjects=1, speeds_m_s=(1.2,), inclines_deg=(10.0,), strides_per_condition=5)
    sub = generate_cohort(one)
    rows = cohort[(cohort[s.SUBJECT] == "VC01") & (cohort[s.TASK_ID] == "s1.2_i10.0")].reset_index(drop=True)
    pd.testing.assert_frame_equal(sub, rows)


# --- layout ----------------------------------------------------------------------------------------
def test_columns_shapes_and_dtypes(cohort: pd.DataFrame) -> None:
    assert len(cohort) == 2 * 2 * 2 * 5 * N
    assert set(cohort.columns) == {*TEXT, s.STEP, *FLOATS}
    assert all(cohort[c].dtype == np.float64 for c in FLOATS)
    assert cohort[s.STEP].dtype == np.int64
    assert sorted(cohort[s.TASK_ID].unique()) == ["s0.8_i-10.0", "s0.8_i10.0", "s1.2_i-10.0", "s1.2_i10.0"]
    row = cohort[cohort[s.TASK_ID] == "s1.2_i-10.0"].iloc[0]
    assert row[s.TASK] == "decline_walking" and row[s.TASK_INFO] == "speed_m_s:1.2,incline_deg:-10.0"
    assert np.isfinite(cohort[list(FLOATS)].to_numpy()).all()


def test_subject_metadata_parses_back(cohort: pd.DataFrame) -> None:
    meta = cohort_subject_metadata(cohort)
    for x in make_subjects(SPEC):
        assert meta[x.code] == {"leg_length_m": x.leg_length_m, "mass_kg": x.mass_kg, "height_m": x.height_m}


def test_strides_time_phase_and_ground_truth(cohort: pd.DataFrame) -> None:
    for _, w in cohort.groupby([s.SUBJECT, s.TASK_ID]):
        t = w[s.TIME_S].to_numpy().reshape(-1, N)
        assert t[0, 0] == 0.0 and np.all(np.diff(t, axis=1) > 0)
        np.testing.assert_allclose(t[1:, 0], t[:-1, -1])  # boundary instants shared, time continuous
        np.testing.assert_array_equal(w[s.STEP].to_numpy().reshape(-1, N), np.arange(5)[:, None] * np.ones(N))
        phase = w[s.PHASE_IPSI].to_numpy().reshape(-1, N)
        np.testing.assert_allclose(phase, 100 * np.linspace(0, 1, N)[None].repeat(5, 0))
        rate = w[s.PHASE_RATE].to_numpy().reshape(-1, N)[:, 0]
        np.testing.assert_allclose(t[:, -1] - t[:, 0], 1 / rate)
        stride = w[s.STRIDE_LENGTH].to_numpy().reshape(-1, N)[:, 0]
        np.testing.assert_allclose(stride, w[s.SPEED].iloc[0] * (t[:, -1] - t[:, 0]))  # l = v T
        step = w[s.STEP_LENGTH].to_numpy().reshape(-1, N)[:, 0]
        np.testing.assert_allclose(step[1:], 0.5 * stride[:-1], rtol=0.03)


def test_events(cohort: pd.DataFrame) -> None:
    for col, lo, hi in ((s.TOE_OFF, 55, 68), (s.HEEL_STRIKE_CONTRA, 49, 51)):
        ev = cohort[cohort[col] == 1.0]
        assert len(ev) == len(cohort) // N  # once per stride
        assert ev[s.PHASE_IPSI].between(lo, hi).all()
    hs = cohort[cohort[s.HEEL_STRIKE] == 1.0]
    assert set(hs[s.PHASE_IPSI]) == {0.0, 100.0} and len(hs) == 2 * len(cohort) // N


# --- realism ----------------------------------------------------------------------------------------
def test_stride_time_cv_is_hausdorff_like(long_walk: pd.DataFrame) -> None:
    period = 1 / long_walk[s.PHASE_RATE].to_numpy()[::N]
    cv = period.std() / period.mean()
    assert 0.01 < cv < 0.04
    assert cv == pytest.approx(0.02, abs=0.004)


def test_stride_length_is_schwartz_step_length_scaled_by_leg_length(long_walk: pd.DataFrame) -> None:
    subj = make_subjects(SPEC)[0]
    st = pd.read_csv("sessions/data/schwartz2008_spatiotemporal.csv", comment="#")
    speed = st[st.parameter == "walking_speed_nondim"]["mean"].to_numpy()
    step = st[st.parameter == "step_length_nondim"]["mean"].to_numpy()
    expected = 2 * np.interp(1.0 / np.sqrt(9.81 * subj.leg_length_m), speed, step) * subj.leg_length_m
    mean_stride = long_walk[s.STRIDE_LENGTH].to_numpy()[::N].mean()
    assert mean_stride == pytest.approx(expected * subj.step_length_scale, rel=0.005)
    assert 1.0 < mean_stride < 1.45  # adult stride at 1 m/s


def test_foot_angle_in_mid_stance_equals_incline(cohort: pd.DataFrame) -> None:
    flat = cohort[cohort[s.PHASE_IPSI].between(15, 30)]
    by_subject = flat.groupby([s.INCLINE, s.SUBJECT])[s.FOOT_ANGLE].mean().apply(np.degrees)
    residual = by_subject - by_subject.index.get_level_values(s.INCLINE).to_numpy()
    assert residual.abs().max() < 3.0  # per subject: its foot-calibration offset (sd 1 deg) and deviations
    assert residual.groupby(level=s.INCLINE).mean().abs().max() < 1.5


def test_push_off_moment_grows_uphill(cohort: pd.DataFrame) -> None:
    peak = cohort.groupby([s.SUBJECT, s.SPEED, s.INCLINE])[s.ANKLE_MOMENT].min().unstack()  # push-off < 0
    assert (peak[10.0] < peak[-10.0]).all()
    mass = {k: v["mass_kg"] for k, v in cohort_subject_metadata(cohort).items()}
    per_kg = -peak.div(peak.index.get_level_values(s.SUBJECT).map(mass).to_numpy(), axis=0)
    assert per_kg.stack().between(0.6, 2.0).all()
    at = cohort.loc[cohort.groupby([s.SUBJECT, s.TASK_ID, s.STEP])[s.ANKLE_MOMENT].idxmin(), s.PHASE_IPSI]
    assert at.between(40, 60).all()


def test_thigh_and_shank_more_flexed_uphill(cohort: pd.DataFrame) -> None:
    hs = cohort[cohort[s.PHASE_IPSI] == 0.0].groupby([s.SUBJECT, s.SPEED, s.INCLINE])
    for col, min_diff in ((s.THIGH_ANGLE, 15.0), (s.SHANK_ANGLE, 8.0)):
        at_hs = hs[col].mean().apply(np.degrees).unstack()
        assert (at_hs[10.0] - at_hs[-10.0] > min_diff).all()


def test_no_jumps_at_stride_boundaries(cohort: pd.DataFrame) -> None:
    for _, w in cohort.groupby([s.SUBJECT, s.TASK_ID]):
        d = drop_duplicate_instants(w)
        boundary = np.flatnonzero(d[s.PHASE_IPSI].to_numpy() == 0.0)[1:] - 1
        for col in SIGNALS:
            step = np.abs(np.diff(d[col].to_numpy()))
            interior = np.delete(step, boundary)
            assert step[boundary].max() <= interior.max() + 0.01 * np.ptp(d[col].to_numpy()), col


def test_a_walk_across_conditions_is_continuous() -> None:
    subj = make_subjects(SPEC)[1]
    schedule = [(0.8, 0.0, 4), (1.2, 10.0, 4), (1.0, -10.0, 4)]
    walk = generate_walk(subj, schedule, np.random.default_rng(0), t0=5.0)
    assert walk[s.TIME_S].iloc[0] == 5.0 and walk[s.TIME_S].is_monotonic_increasing
    np.testing.assert_array_equal(walk[s.STEP].to_numpy()[::N], np.arange(12))
    assert list(walk[s.TASK_ID].unique()) == ["s0.8_i0.0", "s1.2_i10.0", "s1.0_i-10.0"]
    d = drop_duplicate_instants(walk)
    for col in SIGNALS[:10]:
        x = d[col].to_numpy()
        assert np.abs(np.diff(x)).max() <= 0.1 * np.ptp(x), col


def test_heel_moves_with_the_belt_in_foot_flat() -> None:
    subj = make_subjects(SPEC)[0]
    for incline in (-10.0, 0.0, 10.0):
        d = drop_duplicate_instants(generate_walk(subj, [(1.0, incline, 10)], np.random.default_rng(1)))
        t = d[s.TIME_S].to_numpy()
        flat = d[s.PHASE_IPSI].between(15, 30).to_numpy()
        vx = np.gradient(d[s.HEEL_FORWARD].to_numpy(), t)[flat].mean()
        vz = np.gradient(d[s.HEEL_UP].to_numpy(), t)[flat].mean()
        r = np.radians(incline)
        assert vx == pytest.approx(-np.cos(r), abs=0.1)  # posture offsets make the FK heel slip a little
        assert vz == pytest.approx(-np.sin(r), abs=0.04)


# --- sensors and resampling ---------------------------------------------------------------------------
def test_simulate_sensors_drops_duplicates_and_keeps_truth(cohort: pd.DataFrame) -> None:
    walk = cohort[(cohort[s.SUBJECT] == "VC02") & (cohort[s.TASK_ID] == "s0.8_i10.0")]
    out = simulate_sensors(walk, SensorNoise(), np.random.default_rng(0))
    assert list(out.columns[:14]) == [
        s.REPLAY_TIME,
        *s.REPLAY_SIGNALS,
        s.REPLAY_HEEL_STRIKE,
        "gt_phase",
        "gt_phase_rate",
        "gt_stride_length_m",
        "gt_incline_deg",
        "gt_speed_m_s",
        "thigh_angle_deg",
    ]
    assert set(out.columns[14:]) == set(s.CHANNELS) - {*s.REPLAY_SIGNALS, "heel_strike", "thigh_angle_deg"}
    assert len(out) == len(walk) - 4 and np.all(np.diff(out[s.REPLAY_TIME]) > 0)
    assert out[s.REPLAY_HEEL_STRIKE].dtype == np.int64 and out[s.REPLAY_HEEL_STRIKE].sum() == 6
    assert (out.loc[out[s.REPLAY_HEEL_STRIKE] == 1, "gt_phase"].to_numpy()[:-1] == 0.0).all()
    assert out["gt_phase"].between(0, 1).all() and (out["gt_incline_deg"] == 10.0).all()


def test_sensor_noise_has_the_requested_std(long_walk: pd.DataFrame) -> None:
    clean = simulate_sensors(long_walk, SensorNoise(0, 0, 0, 0, 0, 0), np.random.default_rng(0))
    noise = SensorNoise(2.0, 10.0, 7.0, 20.0, 0.01, 0.08)
    noisy = simulate_sensors(long_walk, noise, np.random.default_rng(0))
    for col, sd in zip(s.REPLAY_SIGNALS, noise.__dict__.values(), strict=True):
        assert (noisy[col] - clean[col]).std() == pytest.approx(sd, rel=0.05), col
    d = drop_duplicate_instants(long_walk)
    np.testing.assert_allclose(clean["foot_vel_dps"], np.gradient(_deg(d[s.FOOT_ANGLE]), d[s.TIME_S]))
    assert 200 < clean["foot_vel_dps"].abs().max() < 1000  # deg/s, plausible foot rotation rates
    with pytest.raises(ValueError, match="foot_vel_dps"):
        SensorNoise(foot_vel_dps=-1.0)


def test_simulate_sensors_refuses_several_walks(cohort: pd.DataFrame) -> None:
    with pytest.raises(ValueError, match="one walk"):
        simulate_sensors(cohort, SensorNoise(), np.random.default_rng(0))


def test_resample_walk_gives_a_uniform_grid(long_walk: pd.DataFrame) -> None:
    walk = long_walk[long_walk[s.STEP] < 20]
    out = resample_walk(walk, 100.0)
    t = out[s.TIME_S].to_numpy()
    np.testing.assert_allclose(np.diff(t), 0.01, atol=1e-9)
    end = walk[s.TIME_S].max()
    assert t[0] == 0.0 and t[-1] <= end + 1e-9 and len(out) == int(end * 100) + 1
    assert list(out.columns) == list(walk.columns) and (out.dtypes == walk.dtypes).all()
    unwrapped = out[s.STEP].to_numpy() + out[s.PHASE_IPSI].to_numpy() / 100
    assert np.all(np.diff(unwrapped) > 0) and out[s.PHASE_IPSI].between(0, 100).all()
    assert out[s.HEEL_STRIKE].sum() in (20, 21) and out[s.TOE_OFF].sum() == 20
    first = out.groupby(s.STEP)[s.PHASE_IPSI].min().iloc[1:]  # each stride starts within one grid step
    assert (first <= 100 * 0.01 * out.groupby(s.STEP)[s.PHASE_RATE].first().iloc[1:] + 1e-9).all()
    d = drop_duplicate_instants(walk)  # interpolation: resampled foot angle lies on the original curve
    np.testing.assert_allclose(out[s.FOOT_ANGLE], np.interp(t, d[s.TIME_S], d[s.FOOT_ANGLE]))
    assert (out.groupby(s.STEP)[s.STRIDE_LENGTH].nunique() == 1).all()

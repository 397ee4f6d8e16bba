"""The simulated device's channels of schema version 2 (the version 1 ones: test_cohort.py)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from gaitscope.sessions import schema as s
from gaitscope.sessions.synth.cohort import CohortSpec, SensorNoise, generate_walk, make_subjects, resample_walk
from gaitscope.sessions.synth.imu import G0, ImuSpec
from gaitscope.sessions.synth.sensors import DeviceSensors, simulate_sensors
from gaitscope.sessions.synth.trials import sensor_trial

RATE_HZ = 200.0
V1_COLUMNS = 14  # time, the six replay signals, heel strike, five ground truths, the thigh angle
SUBJECT = make_subjects(CohortSpec())[3]


@pytest.fixture(scope="module")
def trial() -> pd.DataFrame:
    schedule = [(1.2, 0.0, 10), (0.8, 10.0, 10), (1.0, -10.0, 10)]
    return sensor_trial(schedule, subject=3, rate_hz=RATE_HZ, seed=5)[0]


@pytest.fixture(scope="module")
def walk() -> pd.DataFrame:
    return resample_walk(generate_walk(SUBJECT, [(1.0, 0.0, 20)], np.random.default_rng(1)), RATE_HZ)


def test_every_channel_is_simulated_within_its_limits(trial: pd.DataFrame) -> None:
    assert set(s.CHANNELS) <= set(trial.columns)
    assert trial[list(s.CHANNELS)].notna().all().all()
    for name, (lo, hi) in s.SENSOR_LIMITS.items():
        assert trial[name].between(lo, hi).all(), name
    for name in ("foot_contact", "foot_contact_contra"):
        assert trial[name].dtype == bool


def test_the_version_1_channels_keep_their_draws_whatever_the_new_sensors(walk: pd.DataFrame) -> None:
    noisy = DeviceSensors(force_N=50.0, current_A=1.0, imu=ImuSpec(gyro_noise_density_dps=1.0))
    a = simulate_sensors(walk, SensorNoise(), np.random.default_rng(3))
    b = simulate_sensors(walk, SensorNoise(), np.random.default_rng(3), noisy)
    pd.testing.assert_frame_equal(a.iloc[:, :V1_COLUMNS], b.iloc[:, :V1_COLUMNS])
    assert not np.allclose(a["foot_force_N"], b["foot_force_N"])
    pd.testing.assert_frame_equal(a, simulate_sensors(walk, SensorNoise(), np.random.default_rng(3)))  # repeatable


def test_a_gyro_reads_its_segments_rate_with_the_datasheets_noise(walk: pd.DataFrame) -> None:
    out = simulate_sensors(walk, SensorNoise(), np.random.default_rng(8))
    expected = np.sqrt(ImuSpec().noise_sd(RATE_HZ)[0] ** 2 + (1 / 16.4) ** 2 / 12)  # white noise and ADC step
    for side in ("", "_contra"):
        rate = out[f"thigh_vel{side}_dps"].to_numpy()  # clean by default: the thigh's true rate
        gyro = out[f"imu_thigh{side}_gyro_z_dps"].to_numpy()
        (slope, bias), *_ = np.linalg.lstsq(np.c_[rate, np.ones_like(rate)], gyro, rcond=None)
        assert 0.9 < slope < 1.03 and abs(bias) <= 5.0  # scale (3 %), misalignment, bias within +/-5 deg/s
        assert np.std(gyro - slope * rate - bias) == pytest.approx(expected, rel=0.08)


def test_accelerometers_read_gravity_and_the_segments_motion(walk: pd.DataFrame) -> None:
    out = simulate_sensors(walk, SensorNoise(), np.random.default_rng(8))
    pelvis = out[[f"imu_pelvis_accel_{a}_m_s2" for a in "xyz"]].to_numpy()
    assert np.linalg.norm(pelvis, axis=1).mean() == pytest.approx(G0, rel=0.02)  # a trunk sensor: mostly gravity
    foot = out[[f"imu_foot_accel_{a}_m_s2" for a in "xyz"]].to_numpy()
    assert 15.0 < np.abs(foot).max() < 80.0


def test_feet_devices_treadmill_and_centre_of_mass(walk: pd.DataFrame) -> None:
    device = DeviceSensors()
    out = simulate_sensors(walk, SensorNoise(), np.random.default_rng(8), device)
    weight = SUBJECT.mass_kg * 9.81
    total = out["foot_force_N"] + out["foot_force_contra_N"]
    assert total.mean() == pytest.approx(weight, rel=0.01)
    for side in ("", "_contra"):
        contact = out[f"foot_contact{side}"].to_numpy()
        np.testing.assert_array_equal(contact, out[f"foot_force{side}_N"].to_numpy() > 0.05 * weight)
        assert 0.55 < contact.mean() < 0.7
    step = 360 / 2**14
    for name in ("hip_angle_deg", "knee_angle_contra_deg", "ankle_angle_deg"):
        steps = out[name] / step  # a 14-bit encoder, its angle sent with 4 decimals
        np.testing.assert_allclose(steps, np.round(steps), atol=0.5e-4 / step + 1e-9)
    torque = out["commanded_torque_Nm"].to_numpy()
    assert torque.min() == 0.0 and 8.0 < torque.max() <= 30.0
    current = torque / (device.torque_constant_Nm_A * device.transmission_ratio)
    assert np.std(out["motor_current_A"] - current) == pytest.approx(device.current_A, rel=0.1)
    assert (out["belt_speed_m_s"] == 1.0).all()
    hs = out[s.REPLAY_HEEL_STRIKE].to_numpy() > 0
    assert out["step_length_m"].between(0.5, 0.75).all()
    np.testing.assert_allclose(out["step_length_m"].to_numpy()[hs], walk[s.STEP_LENGTH].to_numpy()[hs], atol=5e-5)
    assert (out["com_lateral_m"].iloc[40:100] < 0).all()  # + to the right: the right stance foot is under it
    assert out["com_forward_vel_m_s"].mean() == pytest.approx(1.0, abs=0.02)


def test_thigh_noise_is_opt_in(walk: pd.DataFrame) -> None:
    clean = simulate_sensors(walk, SensorNoise(), np.random.default_rng(8))
    noisy = simulate_sensors(
        walk, SensorNoise(), np.random.default_rng(8), replace(DeviceSensors(), thigh_angle_deg=2.0)
    )
    np.testing.assert_array_equal(clean["thigh_angle_deg"], np.degrees(walk[s.THIGH_ANGLE].to_numpy()))
    assert np.std(noisy["thigh_angle_deg"] - clean["thigh_angle_deg"]) == pytest.approx(2.0, rel=0.1)

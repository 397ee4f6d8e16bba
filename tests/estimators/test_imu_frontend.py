"""The IMU front end: accuracy on the cohort's simulated IMUs, foot-flat resets, calibration, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gaitscope.estimators.imu_calibration import calibrate_standing
from gaitscope.estimators.imu_frontend import CODES, G0, FrontEndConfig, ImuFrontEnd, imu_inputs
from gaitscope.sessions.offline.imu_study import SEGMENTS, trial
from gaitscope.sessions.synth.imu import ImuSpec, draw_errors, imu_readings

SPEC = ImuSpec()


def _standing(angle_deg: float, seconds: float, seed: int, sway_dps: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """A simulated MPU-9250 on a segment held at ``angle_deg`` (swaying at ``sway_dps`` amplitude, 1 Hz)."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(seconds * 100)) / 100
    w = 2 * math.pi
    angle = angle_deg + sway_dps / w * np.sin(w * t)
    rate = sway_dps * np.cos(w * t)
    accel = np.zeros((t.size, 3))
    return imu_readings(angle, rate, accel, 100.0, SPEC, draw_errors(SPEC, rng), rng)


def _run(est: ImuFrontEnd, z: np.ndarray, period: float = 0.01) -> np.ndarray:
    out = np.empty((z.shape[0], len(est.outputs)))
    for i in range(z.shape[0]):
        out[i] = est.step(i * period, z[i])
    return out


@pytest.fixture(scope="module")
def cohort() -> tuple:
    return trial(0, 7)


@pytest.mark.parametrize(("segment", "rmse", "sd"), [("foot", 6.0, 3.0), ("shank", 8.0, 4.0), ("thigh", 4.0, 3.0)])
def test_angles_from_the_cohorts_imus_are_within_tolerance(cohort: tuple, segment: str, rmse: float, sd: float) -> None:
    """Tolerances: about 1.5x the study's figures for this subject (docs/results.md); sd is the error once
    a constant offset (what a standing calibration removes) is taken out."""
    sensors, walk = cohort
    truth = np.degrees(walk[SEGMENTS[segment]].to_numpy())
    t = sensors["time_s"].to_numpy()
    out = _run(ImuFrontEnd(segment), sensors[list(imu_inputs(segment))].to_numpy())
    err = (out[:, 0] - truth)[t - t[0] >= 10.0]
    assert np.sqrt(np.mean(err**2)) < rmse
    assert np.std(err) < sd
    rate_err = (out[:, 1] - np.gradient(truth, t))[t - t[0] >= 10.0]
    assert np.sqrt(np.mean(rate_err**2)) < 6.0  # deg/s: the bias tracker removes the 5 deg/s bias


def test_foot_flat_resets_remove_the_gyro_drift(cohort: tuple) -> None:
    sensors, walk = cohort
    truth = np.degrees(walk[SEGMENTS["foot"]].to_numpy())
    z = sensors[list(imu_inputs("foot"))].to_numpy().copy()
    z[:, 2] += 3.0  # an extra 3 deg/s bias the tracker has not seen: drift without the resets
    late = slice(1000, 2000)
    no_reset = FrontEndConfig(zupt_gain=0.0, k_p=0.0, bias_tau_s=0.0)
    drift = _run(ImuFrontEnd("foot", no_reset), z)[late, 0] - truth[late]
    out = _run(ImuFrontEnd("foot", FrontEndConfig(bias_tau_s=0.0)), z)
    err = out[late, 0] - truth[late]
    assert abs(drift[-1] - drift[0]) > 20.0  # 10 s of the uncorrected bias
    assert np.sqrt(np.mean(err**2)) < 6.0
    assert 0.15 < out[:, 3].mean() < 0.4  # foot-flat on part of each stance
    toe = sensors["gt_phase"].to_numpy()[out[:, 4] > 0.5]
    assert toe.size > 100 and 0.55 < np.mean(toe) < 0.72  # toe-off: normative about 0.6


def test_a_standing_calibration_finds_the_mounting_offset_and_the_front_end_applies_it() -> None:
    gyro, accel = _standing(3.0, 5.0, seed=1)  # standing: shank 3 deg forward
    cal = calibrate_standing({"shank": (gyro, accel)}, 100.0, {"shank": 3.0})
    assert cal.ok and cal.reason == ""
    (shank,) = cal.sensors
    errors = draw_errors(SPEC, np.random.default_rng(1))  # the same sensor _standing(seed=1) simulates
    assert shank.gyro_bias_dps == pytest.approx(tuple(errors.gyro_bias), abs=0.1)
    uncalibrated = _run(ImuFrontEnd("shank"), np.hstack(_standing(-12.0, 5.0, seed=1)))
    est = ImuFrontEnd("shank")
    est.retune(**shank.retune_params())
    out = _run(est, np.hstack(_standing(-12.0, 5.0, seed=1)))  # the same sensor, another posture
    assert abs(uncalibrated[-1, 0] + 12.0) > 1.0  # the mounting shows without the calibration
    assert out[-1, 0] == pytest.approx(-12.0, abs=0.5)
    assert abs(out[-1, 1]) < 0.5


@pytest.mark.parametrize(
    ("sway", "seconds", "why"),
    [(30.0, 5.0, "not still: the gyro moved"), (0.0, 1.0, "only 1.0 s of valid readings")],
)
def test_calibration_refuses_a_subject_who_was_not_still(sway: float, seconds: float, why: str) -> None:
    gyro, accel = _standing(0.0, seconds, seed=2, sway_dps=sway)
    cal = calibrate_standing({"thigh": (gyro, accel)}, 100.0)
    assert not cal.ok and cal.reason.startswith(f"thigh: {why}")
    assert cal.sensors[0].retune_params() == {}


def test_bad_input_holds_and_is_reported() -> None:
    gyro, accel = _standing(10.0, 3.0, seed=3)
    z = np.hstack([gyro, accel])
    est = ImuFrontEnd("thigh", FrontEndConfig(gyro_bias_z_dps=float(gyro[:, 2].mean())))
    base = _run(est, z)
    held = est.step(3.0, np.full(6, np.nan))  # the sensor stops sending
    assert CODES[int(held[2])] == "missing" and held[0] == base[-1, 0] and held[1] == base[-1, 1]
    sat = z[-1].copy()
    sat[2] = 2000.0
    assert CODES[int(est.step(3.01, sat)[2])] == "gyro_saturated"
    assert CODES[int(est.step(3.05, z[-1])[2])] == "sample_rate"  # 40 ms where 10 were expected
    flipped = ImuFrontEnd("thigh")
    z_flip = z.copy()
    z_flip[:, 4] *= -1  # the accelerometer's y axis reversed: gravity reads downward along the thigh
    assert CODES[int(_run(flipped, z_flip)[-1, 2])] == "accel_implausible"


def test_an_upside_down_sensor_is_flagged_while_walking_and_clears_once_upright(cohort: tuple) -> None:
    """Walking, a flipped shank's y axis reads above -0.5 g for a few samples per stride (swing): they must not
    start the count again, or the flip is never flagged."""
    sensors, _ = cohort
    t = sensors["time_s"].to_numpy() - sensors["time_s"].iloc[0]
    z = sensors[list(imu_inputs("shank"))].to_numpy().copy()
    flipped = (t >= 10.0) & (t < 14.0)
    z[flipped, 4] *= -1
    est = ImuFrontEnd("shank")
    codes = np.array([CODES[int(est.step(ti, zi)[2])] for ti, zi in zip(t, z, strict=True)])
    assert not (codes[t < 10.0] == "accel_implausible").any()
    assert (codes == "accel_implausible").any()
    first = t[codes == "accel_implausible"].min()
    assert 11.0 < first < 11.5  # flip_s (1 s) of upside-down readings, and the few in between
    assert (codes[(t > 11.5) & (t < 14.0)] == "accel_implausible").mean() > 0.99
    assert not (codes[t >= 14.05] == "accel_implausible").any()  # upright again: clear at once


finite = st.floats(-1e5, 1e5, allow_nan=False)


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(*[finite] * 6), min_size=1, max_size=40),
    st.sampled_from(["foot", "shank_contra"]),
    st.floats(1e-4, 2.0),
    st.sampled_from(["cf", "fusion"]),
)
def test_finite_input_never_gives_a_non_finite_output(rows: list, segment: str, period: float, method: str) -> None:
    est = ImuFrontEnd(segment, method=method)  # type: ignore[arg-type]
    for i, row in enumerate(rows):
        y = est.step(i * period, np.array(row))
        assert np.isfinite(y).all() and -180.0 <= y[0] < 180.0


def test_declares_the_channels_it_derives() -> None:
    foot = ImuFrontEnd("foot_contra")
    assert foot.name == "imu_foot_contra" and foot.inputs[0] == "imu_foot_contra_gyro_x_dps"
    assert [n for n, _ in foot.outputs] == ["foot_angle_contra_deg", "foot_vel_contra_dps", "imu_code", "foot_flat",
                                            "toe_off"]  # fmt: skip
    with pytest.raises(TypeError, match="no tuning parameter nope"):
        foot.retune(nope=1.0)
    with pytest.raises(ValueError, match="zupt_gain must be <= 1"):
        foot.retune(zupt_gain=2.0)
    with pytest.raises(ValueError, match="no IMU front end for 'pelvis'"):
        ImuFrontEnd("pelvis")
    assert G0 == pytest.approx(9.80665)

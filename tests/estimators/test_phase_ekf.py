"""The compiled phase EKF against the filterpy reference, and its interface."""

import math

import numpy as np
import pytest

from gaitscope.estimators import _kernels
from gaitscope.estimators.basis import n_terms
from gaitscope.estimators.gait_model import SENSOR_VARIANCE, NoiseModel
from gaitscope.estimators.phase_ekf import EKFConfig, PhaseEKF, pseudo_from_stride, stride_from_pseudo
from gaitscope.estimators.reference import ReferencePhaseEKF


def _model(seed: int = 0):
    rng = np.random.default_rng(seed)
    decay = np.exp(-np.arange(n_terms(20)) / 6.0)
    coef = rng.normal(size=(4, 2, 2, n_terms(20))) * decay
    coef[:2] *= 10.0
    coef[2:] *= 0.05
    A = rng.normal(size=(150, 6, 6)) * 0.3
    cov = A @ A.transpose(0, 2, 1)  # positive semi-definite per bin
    return coef, NoiseModel(cov, SENSOR_VARIANCE)


def _measurements(n: int, seed: int = 1) -> np.ndarray:
    rng = np.random.default_rng(seed)
    z = rng.normal(size=(n, 6)) * [10, 80, 10, 80, 0.05, 0.05]
    z[::5, 4:] = np.nan  # heel positions missing now and then
    z[::11, 0:2] = np.nan  # foot IMU missing
    return z


@pytest.mark.parametrize("config", [EKFConfig(), EKFConfig(no_task=True), EKFConfig(q_time_unit=1.0)])
def test_matches_filterpy_reference_to_1e9(config: EKFConfig) -> None:
    coef, noise = _model()
    fast = PhaseEKF(coef, noise, 0.9, config)
    ref = ReferencePhaseEKF(coef, noise, 0.9, config)
    worst = 0.0
    for k, z in enumerate(_measurements(1500)):
        dt = 0.0075 + 0.001 * (k % 3)
        fast.predict(dt)
        ref.predict(dt)
        fast.update(z)
        ref.update(z)
        d = np.abs(fast.x - ref.x)
        d[0] = min(d[0], 1 - d[0])
        worst = max(worst, float(d.max()))
        assert np.abs(fast.P - ref.P).max() < 1e-9
    assert worst < 1e-9


@pytest.mark.parametrize(
    "config", [EKFConfig(), EKFConfig(no_task=True, process_noise_scale=2.5, measurement_noise_scale=0.7)]
)
def test_one_buffer_step_equals_the_kernels_called_apart(config: EKFConfig) -> None:
    """predict / update on the filter's one buffer (one array per compiled call) give the same bits as the
    kernels called on separate arrays, with Q from ``EKFConfig.q_diag`` and the likelihood in Python."""
    coef, noise = _model()
    fast = PhaseEKF(coef, noise, 0.9, config)
    x, P, q = config.initial_state(), config.initial_covariance(), np.zeros(4)
    bins = np.ascontiguousarray(noise.bins * config.measurement_noise_scale)
    terms, h, H, R = np.zeros((4, 7)), np.zeros(6), np.zeros((6, 4)), np.zeros((6, 6))
    y, S, K = np.zeros(6), np.zeros((6, 6)), np.zeros((4, 6))
    for k, z in enumerate(_measurements(600)):
        dt = 0.0075 + 0.001 * (k % 3)
        fast.predict(dt)
        fast.update(z)
        config.q_diag(dt, q)
        _kernels.predict(x, P, dt, q)
        m, maha2, logdet = _kernels.ekf_update(fast.coef, x, P, z, 0.9, bins, terms, h, H, R, y, S, K)
        for mine, theirs in ((fast.x, x), (fast.P, P), (fast.y, y), (fast.S, S), (fast.K, K), (fast.z_pred, h)):
            np.testing.assert_array_equal(mine, theirs)
        np.testing.assert_array_equal(fast.H, H)
        np.testing.assert_array_equal(fast.R, R)
        assert fast.mahalanobis == math.sqrt(maha2)
        assert fast.log_likelihood == (-0.5 * (maha2 + logdet + m * math.log(2.0 * math.pi)) if m else 0.0)


def test_innovation_and_likelihood_are_reported() -> None:
    coef, noise = _model()
    ekf = PhaseEKF(coef, noise, 0.9)
    z = _measurements(2)[1]
    z[4:] = np.nan
    ekf.predict(0.01)
    ekf.update(z)
    assert np.all(np.isfinite(ekf.y[:4])) and np.all(np.isnan(ekf.y[4:]))
    S = ekf.S[:4, :4]
    maha = float(np.sqrt(ekf.y[:4] @ np.linalg.solve(S, ekf.y[:4])))
    assert ekf.mahalanobis == pytest.approx(maha, rel=1e-10)
    expected = -0.5 * (maha**2 + np.log(np.linalg.det(2 * np.pi * S)))
    assert ekf.log_likelihood == pytest.approx(expected, rel=1e-10)


def test_none_skips_and_all_missing_is_a_no_op() -> None:
    coef, noise = _model()
    ekf = PhaseEKF(coef, noise, 0.9)
    ekf.predict(0.01)
    x, P = ekf.x.copy(), ekf.P.copy()
    ekf.update(None)
    ekf.update(np.full(6, np.nan))
    np.testing.assert_array_equal(ekf.x, x)
    np.testing.assert_array_equal(ekf.P, P)


def test_phase_wraps_after_predict() -> None:
    coef, noise = _model()
    ekf = PhaseEKF(coef, noise, 0.9, EKFConfig(initial_phase_rate=1.0))
    ekf.x[0] = 0.995
    ekf.predict(0.01)
    assert ekf.phase == pytest.approx(0.005)


def test_no_task_freezes_stride_and_incline() -> None:
    coef, noise = _model()
    ekf = PhaseEKF(coef, noise, 0.9, EKFConfig(no_task=True))
    x0 = ekf.x.copy()
    for z in _measurements(300):
        ekf.predict(0.01)
        ekf.update(z)
    assert abs(ekf.x[2] - x0[2]) < 1e-9 and abs(ekf.x[3] - x0[3]) < 1e-9


def test_stride_transform_round_trips_and_is_bounded() -> None:
    for l in (0.3, 1.3, 2.0, 3.7):
        assert stride_from_pseudo(pseudo_from_stride(l)) == pytest.approx(l)
    assert 0 < stride_from_pseudo(-1e6) < stride_from_pseudo(1e6) < 4
    with pytest.raises(ValueError, match=r"must be in \(0, 4\)"):
        pseudo_from_stride(4.0)


def test_bad_construction_is_refused() -> None:
    coef, noise = _model()
    with pytest.raises(ValueError, match="coef must have shape"):
        PhaseEKF(coef[:3], noise, 0.9)
    with pytest.raises(ValueError, match="leg_length must be positive"):
        PhaseEKF(coef, noise, 0.0)

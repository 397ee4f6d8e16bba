"""Timing-based estimator and heel-strike detection (seed 000 II-D, III-B)."""

import math

import numpy as np
import pytest

from gaitscope.estimators import _kernels
from gaitscope.estimators.heel_strike import (
    BackupConfig,
    DetectorConfig,
    HeelStrikeBackup,
    HeelStrikeDetector,
    TimingBasedEstimator,
)
from gaitscope.estimators.phase_ekf import PhaseEKF
from tests.estimators.test_phase_ekf import _measurements, _model


def test_tbe_uses_previous_stride_only() -> None:
    tbe = TimingBasedEstimator()
    hs = np.ones(1)
    phases = []
    t = 0.0
    for k in range(1, 401):  # heel strikes at 0, 1.0, 2.2 s
        tbe.predict(0.01)
        t = k * 0.01
        if round(t, 2) in (1.0, 2.2):
            tbe.update(hs)
        phases.append(tbe.phase)
    assert tbe.phase == pytest.approx(((4.0 - 2.2) / 1.2) % 1.0)
    assert phases[49] == pytest.approx(0.5)  # initial period 1 s
    assert phases[149] == pytest.approx(0.5)  # 0.5 s after the first heel strike, previous period 1 s


def test_tbe_ignores_implausible_periods() -> None:
    tbe = TimingBasedEstimator()
    hs = np.ones(1)
    tbe.predict(1.0)
    tbe.update(hs)
    tbe.predict(0.1)
    tbe.update(hs)  # a double event 0.1 s later is not a stride
    assert tbe.x[1] == pytest.approx(1.0)


def _foot(t: np.ndarray, period: float = 1.1) -> tuple[np.ndarray, np.ndarray]:
    # peak of +20 deg at each heel strike (t = k period), foot flat through stance, toes down at push-off
    ph = (t / period) % 1.0
    angle = 20 * np.cos(2 * np.pi * ph) - 25 * np.exp(-(((ph - 0.62) / 0.08) ** 2))
    return angle, np.gradient(angle, t)


def test_detector_finds_each_heel_strike_once() -> None:
    t = np.arange(0, 11.05, 0.01)
    angle, vel = _foot(t)
    det = HeelStrikeDetector()
    found = [tk for tk, a, v in zip(t, angle, vel, strict=True) if det.detect(tk, 0.01, a, v)]
    assert len(found) == 10
    assert np.abs(np.array(found) - 1.1 * np.arange(1, 11)).max() < 0.03


def test_detector_respects_angle_bound_and_refractory_period() -> None:
    det = HeelStrikeDetector(DetectorConfig(max_foot_angle_deg=10.0))
    t = np.arange(0, 5, 0.01)
    angle, vel = _foot(t)
    assert not any(det.detect(tk, 0.01, a, v) for tk, a, v in zip(t, angle, vel, strict=True))
    det = HeelStrikeDetector(DetectorConfig(refractory_s=2.0))
    found = [tk for tk, a, v in zip(t, angle, vel, strict=True) if det.detect(tk, 0.01, a, v)]
    assert np.all(np.diff(found) > 2.0)


def _track_as_before(bk: HeelStrikeBackup, t: float, dt: float, z: np.ndarray, hs: bool) -> None:
    """``HeelStrikeBackup.track``'s update as it was, kernel by kernel from Python (no reset: the test's EKF
    is not reset)."""
    cfg = bk.config
    if hs:
        if bk._last_hs is not None and cfg.min_period <= t - bk._last_hs <= cfg.max_period:
            bk.phase_rate = 1.0 / (t - bk._last_hs)
        bk._last_hs, bk.phase = t, 0.0
    else:
        bk.phase = (bk.phase + bk.phase_rate * dt) % 1.0
    bk.P[0, 0] += cfg.q_rate[0] * dt
    bk.P[1, 1] += cfg.q_rate[1] * dt
    x4 = np.array([bk.phase, bk.phase_rate, bk.x[0], bk.x[1]])
    terms, h, H = np.zeros((4, 7)), np.zeros(6), np.zeros((6, 4))
    _kernels.measurement(bk._coef, x4, bk._leg_length, terms, h, H)
    if bk.ekf is not None:
        R = bk.ekf.R
    else:
        R = np.zeros((6, 6))
        _kernels.noise_at(bk._bins, bk.phase, R)
    H2 = np.ascontiguousarray(H[:, 2:4])
    _kernels.update(bk.x, bk.P, z, h, H2, R, bk._y, bk._S, bk._K, False)
    bk.sse_hp += _kernels.weighted_sse(bk._y, bk._rbar)
    if bk.ekf is not None:
        bk.sse_ekf += _kernels.weighted_sse(bk.ekf.y, bk._rbar)
    if hs:
        bk.sse_ekf = bk.sse_hp = 0.0


@pytest.mark.parametrize("coupled", [True, False])
def test_backup_track_in_one_compiled_call_equals_the_kernels_called_apart(coupled: bool) -> None:
    coef, noise = _model()
    ekf = PhaseEKF(coef, noise, 0.9)
    config = BackupConfig(sse_margin=math.inf)  # no reset of the EKF: both backups see the same EKF
    if coupled:
        mine, theirs = HeelStrikeBackup(ekf, noise, config), HeelStrikeBackup(ekf, noise, config)
    else:
        mine, theirs = (HeelStrikeBackup.standalone(coef, noise, 0.9, config=config) for _ in range(2))
    for k, z in enumerate(_measurements(800)):
        t, hs = 0.01 * (k + 1), k % 97 == 0
        ekf.predict(0.01)
        ekf.update(z)
        mine.track(t, 0.01, z, hs)
        _track_as_before(theirs, t, 0.01, z, hs)
        for a, b in ((mine.x, theirs.x), (mine.P, theirs.P), (mine._y, theirs._y), (mine._K, theirs._K)):
            np.testing.assert_array_equal(a, b)
        assert (mine.sse_hp, mine.sse_ekf, mine.phase) == (theirs.sse_hp, theirs.sse_ekf, theirs.phase)

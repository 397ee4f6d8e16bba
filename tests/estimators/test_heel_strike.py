"""Timing-based estimator and heel-strike detection (seed 000 II-D, III-B)."""

import numpy as np
import pytest

from gaitscope.estimators.heel_strike import DetectorConfig, HeelStrikeDetector, TimingBasedEstimator


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

"""Seed 002's simulated legs: deterministic, at rest before stimulation, IMUs as the models read them."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gaitscope.estimators.sdre import G
from gaitscope.sessions.synth.fes_leg import rest_angle, seated_trial, stimulation, two_link_trial


def test_seated_trial_is_deterministic_and_starts_at_rest() -> None:
    a, b = seated_trial("P1-L", 4, duration_s=6.0), seated_trial("P1-L", 4, duration_s=6.0)
    np.testing.assert_array_equal(a.gyro, b.gyro)
    assert a.t.size == 6001 and a.t_imu.size == 601
    assert a.angles[0, 0] == pytest.approx(rest_angle(a.params))
    assert np.all(a.u[a.t < 3.0] == 0) and np.ptp(a.angles[a.t < 3.0]) < 1e-6  # still before the first burst
    np.testing.assert_allclose(a.knee_deg, np.degrees(math.pi / 2 - a.angles[:, 0]))
    assert 0.1 <= abs(a.gyro_bias_dps[1]) <= 1.0
    # the shank's resting accelerometer reads g sin(angle) on x (the estimators' -g sin x1, negated)
    assert a.accel[0, 1, 0] == pytest.approx(G * math.sin(a.angles[0, 0]), abs=0.1)
    assert a.accel[0, 0, 0] == pytest.approx(G, abs=0.1)  # the thigh lies horizontal


def test_stimulation_is_trapezoid_bursts_after_rest() -> None:
    t = np.array([0.0, 3.0, 3.75, 4.5, 6.0, 7.5, 8.0, 10.0, 11.25])
    expected = [0, 0, 0.1, 0.2, 0.2, 0.2 / 3, 0.0, 0.0, 0.4 * 1.25 / 1.5]  # ramps end 1.5 s after they start
    np.testing.assert_allclose(stimulation(t, np.array([0.2, 0.4])), expected, atol=1e-12)


def test_two_link_trial_follows_a_gait_like_pattern_with_the_bias_asked_for() -> None:
    tr = two_link_trial(2, 0.5, duration_s=4.0)
    assert -25 < tr.hip_deg.min() < -5 and 10 < tr.hip_deg.max() < 30
    assert tr.knee_deg.min() > 0 and 40 < tr.knee_deg.max() < 65
    np.testing.assert_allclose(np.abs(tr.gyro_bias_dps), 0.5)
    # gravity only: the accelerometer's x is g sin(angle) up to its noise
    i = np.searchsorted(tr.t, tr.t_imu)
    np.testing.assert_allclose(tr.accel[:, 1, 0], G * np.sin(tr.angles[i, 1]), atol=0.1)

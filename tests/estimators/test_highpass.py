"""Heel-position high-pass filter (seed 000 II-B)."""

import numpy as np
import pytest
from scipy import signal

from gaitscope.estimators.highpass import HighPassFilter


def test_streaming_equals_batch() -> None:
    t = np.arange(0, 10, 0.01)
    x = np.stack([0.3 * np.sin(2 * np.pi * t) - 0.9, 0.1 * np.cos(2 * np.pi * 0.9 * t) + 0.2 * t], axis=1)
    batch = HighPassFilter(0.01).filter(x)
    stream = HighPassFilter(0.01)
    out = np.array([stream.step(v) for v in x])
    np.testing.assert_allclose(out, batch, atol=1e-12)


def test_starts_in_steady_state_and_removes_offset_and_drift() -> None:
    t = np.arange(0, 20, 0.01)
    x = -0.9 + 0.05 * t  # a constant offset plus a ramp
    y = HighPassFilter(0.01).filter(x)
    assert abs(y[0]) < 1e-12
    assert np.abs(y[-200:]).max() < 1e-3  # the ramp's steady-state response decays for a 2nd-order high-pass


def test_passes_gait_frequencies_and_matches_the_continuous_response() -> None:
    dt, f = 0.01, 1.0  # a stride a second
    t = np.arange(0, 30, dt)
    hp = HighPassFilter(dt)
    amplitude = np.abs(hp.filter(np.sin(2 * np.pi * f * t))[-1000:]).max()
    _, hz = signal.freqz(hp.b, hp.a, worN=[f], fs=1 / dt)
    assert amplitude == pytest.approx(abs(hz[0]), rel=1e-3)
    w = 2 * np.pi * 0.5
    _, hs = signal.freqs([1, 0, 0], [1, 2 * 0.9 * w, w * w], worN=[2 * np.pi * f])
    assert amplitude == pytest.approx(abs(hs[0]), rel=0.05)  # zero-order hold at 100 Hz: within 5 %


def test_refuses_non_positive_period() -> None:
    with pytest.raises(ValueError, match="dt must be positive"):
        HighPassFilter(0.0)

"""Heel-position high-pass filter (seed 000 II-B)."""

import subprocess
import sys

import numpy as np
import pytest
from scipy import signal

from gaitscope.estimators.highpass import HighPassFilter, design


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


@pytest.mark.parametrize(("cutoff_hz", "damping"), [(0.5, 0.9), (1.0, 0.7), (0.2, 1.5)])
def test_design_is_scipys_zoh_discretisation_to_the_bit(cutoff_hz: float, damping: float) -> None:
    """Issue #24: the design without ``scipy.signal`` gives SciPy's coefficients and steady state exactly,
    at the usual rates, at a 100 Hz recording's median period as its CSV rounds it, and at random ones."""
    rng = np.random.default_rng(24)
    periods = [0.01, 0.005, 1 / 60, 1 / 128, 1e-3, 0.009999999999999787, 0.010000000000000009]
    for dt in [*periods, *rng.uniform(1e-4, 0.1, 200), *(0.01 + rng.normal(0.0, 1e-12, 50))]:
        w = 2.0 * np.pi * cutoff_hz
        bz, az, _ = signal.cont2discrete(([1.0, 0.0, 0.0], [1.0, 2.0 * damping * w, w * w]), dt, method="zoh")
        b_ref, a_ref = np.asarray(bz, dtype=np.float64).reshape(-1), np.asarray(az, dtype=np.float64).reshape(-1)
        b, a, zi = design(dt, cutoff_hz, damping)
        assert b.tobytes() == b_ref.tobytes() and a.tobytes() == a_ref.tobytes(), dt
        assert zi.tobytes() == np.asarray(signal.lfilter_zi(b_ref, a_ref), dtype=np.float64).tobytes(), dt


def test_the_pipeline_imports_without_scipy_signal() -> None:
    """Issue #24: ``scipy.signal`` (0.4-0.9 s) is imported by :meth:`HighPassFilter.filter`, not by the
    estimators a replay or a session imports."""
    code = (
        "import sys\nimport numpy as np\nimport gaitscope.estimators.pipeline\n"
        "from gaitscope.estimators.highpass import HighPassFilter\nHighPassFilter(0.01).step(np.zeros(2))\n"
        "print('scipy.signal' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"

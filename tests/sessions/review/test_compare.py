"""The A/B figures and mean stride of ``gaitscope.sessions.review.compare`` on hand-made walks with known answers."""

from __future__ import annotations

import numpy as np
import pytest

from gaitscope.sessions.review.compare import STRIDE_POINTS, Truth, _keep, _wrap, run_figures, stride_mean


def _walk(period: float = 1.0, strides: int = 4, rate: float = 100.0) -> dict[str, np.ndarray]:
    """``strides`` strides of ``period`` s; torque a half sine of 10 N·m peak in each stride's first half."""
    t = np.arange(int(strides * period * rate) + 1) / rate
    phase = (t / period) % 1.0
    hs = np.zeros(t.size, dtype=bool)
    hs[np.isclose(phase, 0.0, atol=1e-9) | np.isclose(phase, 1.0, atol=1e-9)] = True
    torque = np.where(phase < 0.5, 10.0 * np.sin(2 * np.pi * phase), 0.0)
    return {"t": t, "phase": phase, "hs": hs, "torque": torque}


def test_figures_of_a_regular_walk() -> None:
    w = _walk(period=1.0, strides=4)
    n = w["t"].size
    f = run_figures(w["t"], w["torque"], w["phase"], np.full(n, 1.0), np.full(n, 1.3), np.zeros(n), w["hs"])
    assert f.strides == 4
    assert f.peak_torque_Nm == pytest.approx(10.0, abs=1e-3)
    assert f.mean_phase_rate_1_s == pytest.approx(1.0) and f.mean_stride_length_m == pytest.approx(1.3)
    assert f.phase_rmse_pct is None  # no truth, no errors


def test_errors_against_the_truth() -> None:
    w = _walk()
    n = w["t"].size
    truth = Truth("test", (w["phase"] - 0.02) % 1.0, np.full(n, 1.1), np.full(n, 1.0), np.full(n, 2.0))
    f = run_figures(w["t"], w["torque"], w["phase"], np.full(n, 1.0), np.full(n, 1.3), np.zeros(n), w["hs"], truth)
    assert f.phase_rmse_pct == pytest.approx(2.0)  # 2 % everywhere, across the wrap at heel strike too
    assert f.phase_rate_rmse_1_s == pytest.approx(0.1)
    assert f.stride_length_rmse_m == pytest.approx(0.3)
    assert f.incline_rmse_deg == pytest.approx(2.0)


def test_strides_out_of_range_and_missing_values_are_left_out() -> None:
    w = _walk(period=5.0, strides=2)  # 5 s strides: standing, not walking
    n = w["t"].size
    f = run_figures(w["t"], w["torque"], w["phase"], np.full(n, np.nan), np.full(n, 1.0), np.zeros(n), w["hs"])
    assert f.strides == 0 and f.peak_torque_Nm is None and f.mean_phase_rate_1_s is None


def test_mean_stride_of_two_gains() -> None:
    w = _walk(period=1.0, strides=2)
    torque = w["torque"].copy()
    torque[w["t"] >= 1.0] *= 2.0  # the second stride twice the first
    mean, sd, count = stride_mean(w["t"], torque, w["hs"])
    assert count == 2 and mean.shape == sd.shape == (STRIDE_POINTS,)
    assert mean[25] == pytest.approx(15.0, abs=0.05)  # (10 + 20) / 2 at a quarter of the stride
    assert sd[25] == pytest.approx(np.std([10.0, 20.0], ddof=1), abs=0.05)
    assert mean[75] == pytest.approx(0.0)
    mean, sd, count = stride_mean(w["t"][:50], torque[:50], w["hs"][:50])
    assert count == 0 and np.isnan(mean).all()


def test_wrap_and_decimation_keep_extremes() -> None:
    assert _wrap(np.array([0.98 - 0.01, 0.01 - 0.98, 0.5]))[1] == pytest.approx(0.03)
    assert _wrap(np.array([0.99 - 0.01]))[0] == pytest.approx(-0.02)
    y = np.zeros(10_000)
    y[1234], y[8765] = 5.0, -7.0
    keep = _keep([y], y.size, 100)
    assert keep.size <= 100 and 1234 in keep and 8765 in keep and list(keep) == sorted(keep)
    assert list(_keep([y], 50, 100)) == list(range(50))

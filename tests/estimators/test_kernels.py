"""The compiled helpers of :mod:`gaitscope.estimators._kernels` against the Python they replace."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gaitscope.estimators import _kernels
from gaitscope.estimators.torque import TorqueProfile


def _python_health(y: np.ndarray, P: np.ndarray | None, max_variance: float) -> bool:
    """The estimator stack's health rule as it was in Python: finite sums (overflow fails), variances in range."""
    if not math.isfinite(sum(y.tolist())):
        return False
    if P is None:
        return True
    flat = P.ravel().tolist()
    if not math.isfinite(sum(flat)):
        return False
    d = flat[:: P.shape[0] + 1]
    return not (min(d) < 0 or max(d) > max_variance)


@pytest.mark.parametrize("n", [1, 3, 6])
def test_the_stack_health_check_decides_as_the_python_rule(n: int) -> None:
    rng = np.random.default_rng(n)
    specials = [math.nan, math.inf, -math.inf, 1e308, -1e308, -1e-12, 2e3]
    for _ in range(3000):
        y = rng.normal(size=n) * 10.0
        A = rng.normal(size=(n, n))
        P = A @ A.T
        for arr in (y, P.reshape(-1)):
            if rng.random() < 0.3:
                arr[rng.integers(arr.size)] = specials[rng.integers(len(specials))]
        if rng.random() < 0.2:
            P[np.diag_indices(n)] = 1e308  # a finite diagonal whose sum overflows
        expected = _python_health(y, P, 1e3)
        assert (_kernels.finite_sum(y) and _kernels.covariance_ok(P, 1e3)) == expected
        assert _kernels.outputs_ok(y, P, 1e3) == expected
        assert _kernels.finite_sum(y) == _python_health(y, None, 1e3)


def test_the_torque_at_a_state_is_the_gait_models_value_bit_for_bit() -> None:
    rng = np.random.default_rng(0)
    coef = rng.normal(size=(2, 2, 41)) * np.exp(-np.arange(41) / 6.0)
    profile = TorqueProfile(coef)
    coef4, terms = np.ascontiguousarray(coef[None]), np.empty((1, 7))
    for p, l, r in rng.uniform((0.0, 0.5, -15.0), (0.7, 2.5, 15.0), size=(2000, 3)):
        _kernels.model_terms(coef4, p, l, r, terms)
        tau = profile.scale * 70.0 * float(terms[0, 0])
        expected = max(tau, 0.0) if p <= profile.cutoff_phase and math.isfinite(tau) else 0.0
        assert profile.torque_at(p, l, r, 70.0, 1e9) == expected

"""Constrained least squares of the gait model and the heteroscedastic noise model."""

import numpy as np
import pytest

from gaitscope.estimators.basis import n_terms, regressor
from gaitscope.estimators.gait_model import (
    OUT_FOOT,
    SENSOR_VARIANCE,
    NoiseModel,
    evaluate,
    fit_outputs,
    gait_constraints,
    gram,
    residual_covariance,
    solve_constrained,
)

ORDER = 20


def _data(rng: np.random.Generator, n: int = 20_000):
    p = rng.uniform(0, 1, n)
    l = rng.choice([1.1, 1.3, 1.5], n) + rng.normal(0, 0.03, n)
    r = rng.choice(np.arange(-10, 10.1, 2.5), n)
    y = np.stack(
        [
            # meets both constraints: r at l = 0, and d/dl = 0 at p = 0.2
            r
            + l * 20 * (np.sin(2 * np.pi * p) - np.sin(0.4 * np.pi))
            + 0.5 * l * r * (np.cos(2 * np.pi * p) - np.cos(0.4 * np.pi)),
            l * 30 * np.cos(2 * np.pi * p) + 0.3 * r * l,
            l * 0.2 * np.sin(2 * np.pi * p),
            l * 0.05 * np.cos(4 * np.pi * p),
        ],
        axis=1,
    )
    return p, l, r, y + rng.normal(0, 1.0, y.shape) * [1, 1, 0.01, 0.01]


def test_constraints_hold_to_1e8() -> None:
    p, l, r, y = _data(np.random.default_rng(0))
    coef = fit_outputs(gram(p, l, r, y, ORDER), ORDER)
    assert coef.shape == (4, 2, 2, n_terms(ORDER))
    for o in range(4):
        C, d = gait_constraints(ORDER, o)
        assert np.abs(C @ coef[o].reshape(-1) - d).max() < 1e-8
    # eq. 11: with both constraints the foot angle at p = 0.2 equals the incline for every stride length
    for l_val in (0.5, 1.0, 1.7, 3.0):
        foot = evaluate(coef, np.array([0.2, 0.2]), np.array([l_val, l_val]), np.array([-7.0, 4.0]))[:, OUT_FOOT]
        np.testing.assert_allclose(foot, [-7.0, 4.0], atol=1e-7)


def test_fit_recovers_a_model_that_meets_the_constraints() -> None:
    p, l, r, y = _data(np.random.default_rng(1), 40_000)
    coef = fit_outputs(gram(p, l, r, y, ORDER), ORDER)
    rms = np.sqrt(np.mean((evaluate(coef, p, l, r) - y) ** 2, axis=0))
    np.testing.assert_allclose(rms, [1.0, 1.0, 0.01, 0.01], rtol=0.03)  # the noise level: no model error


def test_unconstrained_solution_is_ordinary_least_squares() -> None:
    rng = np.random.default_rng(3)
    A = rng.normal(size=(300, 12))
    y = rng.normal(size=300)
    x = solve_constrained(A.T @ A, A.T @ y, None, None)
    np.testing.assert_allclose(x, np.linalg.lstsq(A, y, rcond=None)[0], atol=1e-10)


def test_dependent_constraints_are_handled() -> None:
    rng = np.random.default_rng(4)
    A = rng.normal(size=(200, 6))
    y = rng.normal(size=200)
    C = np.array([[1.0, 1, 0, 0, 0, 0], [2.0, 2, 0, 0, 0, 0], [0, 0, 1.0, 0, 0, 0]])
    d = np.array([1.0, 2.0, 3.0])
    x = solve_constrained(A.T @ A, A.T @ y, C, d)
    np.testing.assert_allclose(C @ x, d, atol=1e-12)


def test_residual_covariance_is_uncentred_per_bin() -> None:
    p = np.repeat(np.arange(150) / 150, 4)
    e = np.tile(
        np.array([[1.0, 0, 0, 0, 0, 0], [-1, 0, 0, 0, 0, 0], [1, 0, 0, 0, 0, 0], [1, 0, 0, 0, 0, 0]]),
        (150, 1),
    )
    cov = residual_covariance(p, e)
    assert cov.shape == (150, 6, 6)
    np.testing.assert_allclose(cov[:, 0, 0], 4 / 3)  # sum of squares / (N - 1), no mean removed


def test_residual_covariance_needs_every_bin() -> None:
    with pytest.raises(ValueError, match="fewer than 2 residuals"):
        residual_covariance(np.zeros(10), np.ones((10, 6)))


def test_noise_interpolates_linearly_and_wraps() -> None:
    cov = np.zeros((150, 6, 6))
    cov[0] = np.eye(6)
    noise = NoiseModel(cov, SENSOR_VARIANCE)
    np.testing.assert_allclose(noise.at(0.0), np.eye(6) + np.diag(SENSOR_VARIANCE))
    np.testing.assert_allclose(noise.at(0.5 / 150), 0.5 * np.eye(6) + np.diag(SENSOR_VARIANCE))
    np.testing.assert_allclose(noise.at(149.5 / 150), 0.5 * np.eye(6) + np.diag(SENSOR_VARIANCE))
    np.testing.assert_allclose(noise.mean(), np.eye(6) / 150 + np.diag(SENSOR_VARIANCE))


def test_regressor_matches_evaluate() -> None:
    coef = np.random.default_rng(5).normal(size=(4, 2, 2, n_terms(3)))
    p, l, r = np.array([0.25]), np.array([1.2]), np.array([3.0])
    np.testing.assert_allclose(evaluate(coef, p, l, r)[0], coef.reshape(4, -1) @ regressor(p, l, r, 3)[0])

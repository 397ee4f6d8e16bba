"""Kronecker regressor and its analytic derivatives against finite differences."""

import numpy as np
import pytest

from gaitscope.estimators import _kernels
from gaitscope.estimators.basis import fourier, linear, n_terms, regressor

ORDER = 20


@pytest.fixture
def states() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(1)
    return rng.uniform(0, 1, 50), rng.uniform(0.8, 2.0, 50), rng.uniform(-10, 10, 50)


def test_shapes_and_kronecker_order() -> None:
    p, l, r = np.array([0.3]), np.array([1.4]), np.array([5.0])
    A = regressor(p, l, r, ORDER)
    assert A.shape == (1, 4 * n_terms(ORDER)) == (1, 164)
    expected = np.kron(np.kron(linear(r)[0], linear(l)[0]), fourier(p, ORDER)[0])
    np.testing.assert_allclose(A[0], expected, rtol=0, atol=0)


def test_fourier_is_periodic() -> None:
    p = np.array([0.1, 0.7])
    np.testing.assert_allclose(fourier(p, ORDER), fourier(p + 1.0, ORDER), atol=1e-12)


@pytest.mark.parametrize(("dp", "dl", "dr"), [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, 0, 1), (2, 0, 0)])
def test_derivatives_match_finite_differences(states, dp: int, dl: int, dr: int) -> None:
    p, l, r = states
    h = 1e-5

    def f(pp, ll, rr, ddp=0):
        return regressor(pp, ll, rr, ORDER, dp=ddp)

    # differentiate numerically in l and r, analytically-lower order in p, then compare
    if dp == 2:
        num = (f(p + h, l, r, 1) - f(p - h, l, r, 1)) / (2 * h)
    else:
        base_dp = 0
        g = lambda pp, ll, rr: f(pp, ll, rr, base_dp)  # noqa: E731
        if dp == 1:
            g0 = g
            g = lambda pp, ll, rr: (g0(pp + h, ll, rr) - g0(pp - h, ll, rr)) / (2 * h)  # noqa: E731
        if dl == 1:
            num = (g(p, l + h, r) - g(p, l - h, r)) / (2 * h)
        elif dr == 1:
            num = (g(p, l, r + h) - g(p, l, r - h)) / (2 * h)
        else:
            num = g(p, l, r)
    ana = regressor(p, l, r, ORDER, dp=dp, dl=dl, dr=dr)
    scale = np.abs(ana).max()
    assert np.abs(num - ana).max() / scale < 1e-6


def test_compiled_terms_equal_vectorised(states) -> None:
    rng = np.random.default_rng(2)
    coef = rng.normal(size=(4, 2, 2, n_terms(ORDER)))
    p, l, r = states
    out = np.empty((4, 7))
    derivs = [(0, 0, 0), (1, 0, 0), (2, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, 0, 1)]
    for k in range(5):
        _kernels.model_terms(coef, p[k], l[k], r[k], out)
        for j, (a, b, c) in enumerate(derivs):
            row = regressor(p[k : k + 1], l[k : k + 1], r[k : k + 1], ORDER, dp=a, dl=b, dr=c)[0]
            expected = coef.reshape(4, -1) @ row
            np.testing.assert_allclose(out[:, j], expected, rtol=1e-10, atol=1e-9)


def test_bad_derivative_order_is_refused() -> None:
    with pytest.raises(ValueError, match="derivative must be 0, 1 or 2"):
        fourier(np.array([0.1]), 3, derivative=3)

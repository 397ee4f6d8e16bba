"""Sparse GP regression (:mod:`gaitscope.estimators.gp`): the frozen numpy predictor against GPy's own prediction,
FITC against an exact GP, the analytic mean derivative against finite differences, the compiled stack
against the numpy path, and deterministic fits."""

from __future__ import annotations

import numpy as np
import pytest

from gaitscope.estimators.gp import FitOptions, GPStack, SparseGP, fit_gpy, fit_sparse_gp, from_gpy, rbf_mean_2d


def _random_gp(rng: np.random.Generator, m: int, d: int) -> SparseGP:
    """An arbitrary (not fitted) sparse GP: the prediction formulas do not care where the numbers came from."""
    a = rng.standard_normal((m, m))
    return SparseGP(
        Z=rng.uniform(0.0, 1.0, (m, d)),
        lengthscale=rng.uniform(0.1, 0.4, d),
        variance=2.0,
        noise=0.3,
        alpha=rng.standard_normal(m),
        w_inv=0.05 * (a + a.T),
        offset=1.5,
    )


def _exact_gp(x: np.ndarray, y: np.ndarray, ell: float, sf2: float, sn2: float, xs: np.ndarray) -> tuple:
    """The dense GP's predictive mean and variance (with noise) on standardized targets, by the textbook
    formulas (Rasmussen and Williams eq. 2.25-2.26)."""
    mean, std = y.mean(), y.std()
    yn = (y - mean) / std

    def k(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return sf2 * np.exp(-0.5 * (a[:, None] - b[None, :]) ** 2 / ell**2)

    inv = np.linalg.inv(k(x, x) + sn2 * np.eye(x.size))
    ks = k(xs, x)
    return mean + std * ks @ inv @ yn, std**2 * (sf2 - np.einsum("ij,jk,ik->i", ks, inv, ks) + sn2)


def _hyper(model: object) -> tuple[float, float, float]:
    m: object = model
    return (
        float(m.kern.lengthscale.values[0]),  # type: ignore[attr-defined]
        float(m.kern.variance.values[0]),  # type: ignore[attr-defined]
        float(m.likelihood.variance.values[0]),  # type: ignore[attr-defined]
    )


@pytest.fixture(scope="module")
def data() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(3)
    x = np.sort(rng.uniform(0.0, 1.0, 300))
    return x, 30.0 * np.sin(5.0 * x) + 10.0 + rng.normal(0.0, 1.0, x.size)


@pytest.mark.parametrize("d", [1, 2])
def test_mean_gradient_matches_central_differences(d: int) -> None:
    g = _random_gp(np.random.default_rng(d), 25, d)
    x = np.random.default_rng(10 + d).uniform(-0.2, 1.2, (40, d))
    h = 1e-6
    fd = np.stack([(g.mean(x + h * e) - g.mean(x - h * e)) / (2 * h) for e in np.eye(d)], axis=1)
    np.testing.assert_allclose(g.gradient(x), fd, rtol=1e-6, atol=1e-6)
    if d == 1:
        np.testing.assert_allclose(g.derivative(x[:, 0]), fd[:, 0], rtol=1e-6, atol=1e-6)


def test_fitted_mean_derivative_matches_central_differences(data: tuple[np.ndarray, np.ndarray]) -> None:
    g = fit_sparse_gp(*data, FitOptions(max_iters=50))
    xs = np.linspace(0.0, 1.0, 101)
    fd = (g.mean(xs + 1e-6) - g.mean(xs - 1e-6)) / 2e-6
    np.testing.assert_allclose(g.derivative(xs), fd, rtol=1e-5, atol=1e-4)
    # and it is the derivative of the data's curve (30 sin 5x), away from the ends
    inner = (xs > 0.1) & (xs < 0.9)
    assert np.max(np.abs(g.derivative(xs[inner]) - 150.0 * np.cos(5.0 * xs[inner]))) < 15.0


def test_fitc_with_every_training_input_inducing_is_the_exact_gp() -> None:
    rng = np.random.default_rng(4)
    x = np.sort(rng.uniform(0.0, 1.0, 40))
    y = 30.0 * np.sin(5.0 * x) + 10.0 + rng.normal(0.0, 1.0, x.size)
    model = fit_gpy(x, y, FitOptions(n_inducing=x.size), Z=x[:, None])
    g = from_gpy(model)
    xs = np.linspace(-0.1, 1.1, 50)
    mean, var = _exact_gp(x, y, *_hyper(model), xs)
    np.testing.assert_allclose(g.mean(xs), mean, atol=0.01)  # 3e-4 of the range: GPy adds 1e-6 jitter to Kmm
    np.testing.assert_allclose(g.variance_at(xs), var, rtol=2e-3)


def test_fitc_with_25_inducing_points_nearly_agrees_with_the_exact_gp(data: tuple[np.ndarray, np.ndarray]) -> None:
    x, y = data
    model = fit_gpy(x, y, FitOptions())
    g = from_gpy(model)
    assert g.n_inducing == 25
    xs = np.linspace(0.0, 1.0, 50)
    mean, var = _exact_gp(x, y, *_hyper(model), xs)
    assert np.max(np.abs(g.mean(xs) - mean)) < 0.05 * np.sqrt(g.noise)
    np.testing.assert_allclose(g.variance_at(xs), var, rtol=0.01)
    assert np.sqrt(g.noise) == pytest.approx(1.0, rel=0.15)  # the noise it was made with


@pytest.mark.parametrize("d", [1, 2])
def test_numpy_prediction_equals_gpy_predict(d: int) -> None:
    rng = np.random.default_rng(5)
    x = rng.uniform(0.0, 1.0, (400, d))
    y = np.sin(5.0 * x[:, 0]) * (1.0 + x[:, -1]) + rng.normal(0.0, 0.05, 400)
    model = fit_gpy(x, y, FitOptions(n_inducing=25 if d == 1 else 100, max_iters=60))
    g = from_gpy(model)
    xs = rng.uniform(-0.3, 1.3, (60, d))  # inside and beyond the data
    mean, var = model.predict(xs)
    np.testing.assert_allclose(g.mean(xs), mean[:, 0], rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(g.variance_at(xs), var[:, 0], rtol=1e-7)
    latent = model.predict_noiseless(xs)[1][:, 0]
    np.testing.assert_allclose(g.variance_at(xs, noise=False), latent, rtol=1e-6, atol=1e-12)
    if d == 2:
        il2 = 1.0 / g.lengthscale**2
        compiled = [rbf_mean_2d(a, b, g.Z, il2, g.alpha, g.offset) for a, b in xs]
        np.testing.assert_allclose(compiled, g.mean(xs), rtol=1e-12, atol=1e-12)


def test_stack_evaluates_every_gp_as_the_numpy_path() -> None:
    rng = np.random.default_rng(6)
    gps = [_random_gp(rng, m, 1) for m in (25, 7, 25, 12)]  # unequal sizes: the stack pads
    stack = GPStack(gps)
    mu, dmu, var = np.zeros(4), np.zeros(4), np.zeros(4)
    for x in (-0.5, 0.0, 0.37, 1.0, 2.0):
        stack.evaluate(x, mu, dmu, var)
        np.testing.assert_allclose(mu, [g.mean(x)[0] for g in gps], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(dmu, [g.derivative(x)[0] for g in gps], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(var, [g.variance_at(x)[0] for g in gps], rtol=1e-12, atol=1e-12)


def test_fits_are_deterministic_and_round_trip_through_arrays(data: tuple[np.ndarray, np.ndarray]) -> None:
    a, b = (fit_sparse_gp(*data, FitOptions(max_iters=40)) for _ in range(2))
    for k, v in a.to_arrays().items():
        np.testing.assert_array_equal(v, b.to_arrays()[k])
    c = SparseGP.from_arrays(a.to_arrays())
    xs = np.linspace(0.0, 1.0, 7)
    np.testing.assert_array_equal(c.predict(xs), a.predict(xs))


def test_inducing_inputs_start_at_training_inputs_and_stay_there(data: tuple[np.ndarray, np.ndarray]) -> None:
    x, y = data
    g = fit_sparse_gp(x, y)
    assert set(g.Z[:, 0]) <= set(x)  # seed 003: "a fixed-size active set of training points"
    assert g.Z[0, 0] == x.min() and g.Z[-1, 0] == x.max()


def test_bad_training_data_is_refused() -> None:
    x = np.linspace(0.0, 1.0, 20)
    with pytest.raises(ValueError, match="constant"):
        fit_gpy(x, np.full(20, 3.0))
    with pytest.raises(ValueError, match="finite"):
        fit_gpy(x, np.where(x > 0.5, np.nan, x))
    with pytest.raises(ValueError, match="differ"):
        fit_gpy(x, x[:10])
    with pytest.raises(ValueError):
        FitOptions(n_inducing=0)

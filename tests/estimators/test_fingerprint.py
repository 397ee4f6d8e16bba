"""Gait fingerprints (seed 004): the map against a direct PCA, the LS solve, the EKF against its numpy oracle."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gaitscope.estimators.fingerprint import FingerprintEKF, FingerprintMap, basis, basis_dp, fit_map, fit_subject
from gaitscope.estimators.protocol import Estimator, output_names


def _subjects(n: int = 8, seed: int = 3) -> tuple[list[tuple[np.ndarray, np.ndarray, np.ndarray]], np.ndarray]:
    """Synthetic subjects: a shared thigh curve with a per-subject offset, amplitude and timing, at three
    stride lengths; returns the walks and the true per-subject parameters."""
    rng = np.random.default_rng(seed)
    p = np.tile(np.arange(150) / 150.0, 3)
    l = np.repeat([1.0, 1.2, 1.4], 150)
    walks, truth = [], []
    for _ in range(n):
        off, amp, shift = rng.normal(0, 6), 1 + rng.normal(0, 0.1), rng.normal(0, 0.02)
        theta = off + amp * (20 * np.cos(2 * np.pi * (p - shift)) + 5 * l * np.sin(4 * np.pi * p)) + 3 * l
        walks.append((p, l, theta + rng.normal(0, 0.3, p.size)))
        truth.append((off, amp, shift))
    return walks, np.array(truth)


def test_the_basis_derivative_is_the_phase_derivative_of_the_basis() -> None:
    p, l, h = np.linspace(0.01, 0.99, 40), np.full(40, 1.3), 1e-6
    numeric = (basis(p + h, l) - basis(p - h, l)) / (2 * h)
    assert np.allclose(basis_dp(p, l), numeric, atol=1e-5)
    assert basis(p, l).shape == (40, 14)


def test_the_map_is_pca_of_the_fits_in_rmse_space() -> None:
    walks, _ = _subjects()
    fmap = fit_map(walks, n_components=3)
    # direct construction: fits, G over all samples, differences whitened by G^(1/2), SVD
    fits = np.array([np.linalg.lstsq(basis(p, l), th, rcond=None)[0] for p, l, th in walks])
    A = np.vstack([basis(p, l) for p, l, _ in walks])
    G = A.T @ A / A.shape[0]
    w, V = np.linalg.eigh(G)
    root = V @ np.diag(np.sqrt(w)) @ V.T
    X = (fits - fits.mean(axis=0)) @ root
    _, sv, Vt = np.linalg.svd(X, full_matrices=False)
    assert np.allclose(fmap.xi_avg, fits.mean(axis=0))
    assert np.allclose(np.cumsum(sv**2)[:3] / np.sum(sv**2), fmap.explained[:3])
    for i in range(3):  # each row maps back to a unit RMSE-space direction, up to sign
        direction = fmap.p_map[i] @ root
        assert math.isclose(abs(direction @ Vt[i]), 1.0, rel_tol=1e-8)
        # g = 1 changes the prediction by 1 deg RMS over the training data
        assert fmap.rms_deg(fmap.xi(np.eye(3)[i]), fmap.xi_avg) == pytest.approx(1.0)


def test_the_threshold_picks_the_fewest_components_that_pass_it() -> None:
    walks, _ = _subjects()
    fmap = fit_map(walks, variance_threshold=0.99)
    k = fmap.n_components
    assert fmap.explained[k - 1] > 0.99 and (k == 1 or fmap.explained[k - 2] <= 0.99)


def test_the_ls_fingerprint_minimises_the_angle_error_within_the_map() -> None:
    walks, _ = _subjects()
    fmap = fit_map(walks[1:], n_components=3)
    p, l, theta = walks[0]
    g = fmap.ls_fingerprint(p, l, theta)
    A = basis(p, l)
    best = np.sqrt(np.mean((A @ fmap.xi(g) - theta) ** 2))
    rng = np.random.default_rng(0)
    for _ in range(20):
        other = g + rng.normal(0, 0.3, g.size)
        assert np.sqrt(np.mean((A @ fmap.xi(other) - theta) ** 2)) >= best
    assert best < np.sqrt(np.mean((A @ fmap.xi_avg - theta) ** 2))
    # the normal equations of eq. 40: (P A^T A P^T) g = P A^T (theta - A xi_avg)
    P = fmap.p_map
    assert np.allclose(P @ A.T @ A @ P.T @ g, P @ A.T @ (theta - A @ fmap.xi_avg), rtol=1e-8, atol=1e-6)


def test_bad_training_data_is_refused_with_the_reason() -> None:
    walks, _ = _subjects(3)
    with pytest.raises(ValueError, match="at least two"):
        fit_map(walks[:1])
    p, l, th = walks[0]
    with pytest.raises(ValueError, match="finite"):
        fit_subject(p, l, np.where(np.arange(th.size) == 5, np.nan, th))
    with pytest.raises(ValueError, match="do not determine"):
        fit_subject(p[:10], l[:10], th[:10])
    with pytest.raises(ValueError, match="do not determine"):  # one stride length: l and 1 cannot be told apart
        fit_subject(p[:150], l[:150], th[:150])
    with pytest.raises(ValueError, match="n_components"):
        fit_map(walks, n_components=5)


def _walk(fmap: FingerprintMap, n: int = 4000) -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(n) * 0.008
    p = (t * 0.95) % 1.0
    l = np.full(n, 1.25)
    theta = basis(p, l) @ fmap.xi_avg
    vel = 0.95 * basis_dp(p, l) @ fmap.xi_avg
    return t, np.stack([theta, vel], axis=1)


@pytest.mark.parametrize("mode", ["avg", "ls", "gf"])
def test_the_compiled_step_is_the_numpy_filter(mode: str) -> None:
    walks, _ = _subjects()
    fmap = fit_map(walks[1:], n_components=3)
    g = fmap.ls_fingerprint(*walks[0]) if mode == "ls" else None
    t, z = _walk(fmap, 1500)
    fast, oracle = FingerprintEKF(fmap, mode=mode, g=g), FingerprintEKF(fmap, mode=mode, g=g)  # type: ignore[arg-type]
    for i in range(t.size):
        zi = z[i].copy()
        if i % 50 == 7:
            zi[i % 2] = np.nan  # a missing channel: that row is skipped
        y = fast.step(float(t[i]), zi)
        oracle.predict(0.0 if i == 0 else float(t[i] - t[i - 1]))
        oracle.update(zi)
        assert np.allclose(fast.x, oracle.x, atol=1e-10) and np.allclose(fast.P, oracle.P, atol=1e-10)
        assert y[3] == pytest.approx(oracle._pred, abs=1e-9)


def test_the_filter_tracks_the_model_it_runs_and_meets_the_protocol() -> None:
    walks, _ = _subjects()
    fmap = fit_map(walks, n_components=3)
    ekf = FingerprintEKF(fmap, mode="avg")
    assert isinstance(ekf, Estimator)
    assert output_names(ekf) == ("phase", "phase_rate", "stride_length_m", "thigh_pred_deg")
    assert output_names(FingerprintEKF(fmap, mode="gf"))[-3:] == ("g1", "g2", "g3")
    t, z = _walk(fmap)
    for i in range(t.size):
        y = ekf.step(float(t[i]), z[i])
    true_p = (t[-1] * 0.95) % 1.0
    assert min(abs(y[0] - true_p), 1 - abs(y[0] - true_p)) < 0.02
    assert y[1] == pytest.approx(0.95, abs=0.03) and y[2] == pytest.approx(1.25, abs=0.1)


def test_a_bad_fingerprint_or_mode_is_refused() -> None:
    walks, _ = _subjects()
    fmap = fit_map(walks, n_components=3)
    with pytest.raises(ValueError, match="3 finite components"):
        FingerprintEKF(fmap, mode="ls", g=np.array([1.0, np.nan, 0.0]))
    with pytest.raises(ValueError, match="mode"):
        FingerprintEKF(fmap, mode="xyz")  # type: ignore[arg-type]
    ekf = FingerprintEKF(fmap)
    with pytest.raises(ValueError, match="positive"):
        ekf.retune(measurement_noise_scale=-1.0)
    with pytest.raises(TypeError, match="no tuning parameter"):
        ekf.retune(gain=1.0)


@settings(max_examples=60, deadline=None)
@given(
    z=st.lists(
        st.tuples(
            st.floats(min_value=-1e6, max_value=1e6) | st.just(math.nan),
            st.floats(min_value=-1e7, max_value=1e7) | st.just(math.nan),
        ),
        min_size=1,
        max_size=60,
    ),
    mode=st.sampled_from(["avg", "gf"]),
)
def test_whatever_it_reads_the_state_stays_in_range_and_the_covariance_symmetric(
    z: list[tuple[float, float]], mode: str
) -> None:
    walks, _ = _subjects(5)
    fmap = fit_map(walks, n_components=2)
    ekf = FingerprintEKF(fmap, mode=mode)  # type: ignore[arg-type]
    for i, (a, v) in enumerate(z):
        y = ekf.step(0.01 * (i + 1), np.array([a, v]))
        if not np.isfinite(y).all():
            break  # a stack marks such an estimator failed; nothing else to check
        assert 0.0 <= y[0] < 1.0 and y[1] >= 0.5 and 0.0 <= y[2] <= 2.0
        assert np.allclose(ekf.P, ekf.P.T)


def test_a_new_fingerprint_takes_over_at_the_next_heel_strike_only() -> None:
    walks, _ = _subjects()
    fmap = fit_map(walks, n_components=3)
    ekf = FingerprintEKF(fmap, mode="ls", g=np.zeros(3))
    t, z = _walk(fmap, 600)
    for i in range(300):
        y = ekf.step(float(t[i]), z[i])
    before = ekf._xi_fixed.copy()
    ekf.personalize(np.array([2.0, 0.0, 0.0]))
    wrapped_at = None
    for i in range(300, 600):
        phase_before = float(ekf.x[0])
        y = ekf.step(float(t[i]), z[i])
        if wrapped_at is None and y[0] < phase_before:
            wrapped_at = i
        changed = not np.allclose(ekf._xi_fixed, before)
        assert changed == (wrapped_at is not None), (i, phase_before, y[0])
    assert wrapped_at is not None and np.allclose(ekf._xi_fixed, fmap.xi(np.array([2.0, 0.0, 0.0])))
    with pytest.raises(ValueError, match="only the personalized filter"):
        FingerprintEKF(fmap, mode="gf").personalize(np.zeros(3))
    with pytest.raises(ValueError, match="3 finite components"):
        ekf.personalize(np.array([1.0, math.inf, 0.0]))

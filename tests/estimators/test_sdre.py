"""Seed 002's SDRE estimator, its EKF and rotation-matrix comparators, and the stack estimator."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from gaitscope.estimators.protocol import Estimator
from gaitscope.estimators.sdre import (
    ContinuousFilter,
    G,
    KneeParams,
    TwoLinkParams,
    complementary_angle,
    initial_angle,
    rmx_knee_angle,
    rotation_z,
)
from gaitscope.estimators.sdre_estimator import SDREKnee

KNEE = KneeParams.from_table1("P1-L")
LINKS = TwoLinkParams.from_anthropometry(knee=KNEE)


def _measurements(n: int, dt: float) -> np.ndarray:
    t = np.arange(n) * dt
    return np.column_stack([0.4 * np.cos(2 * t), -G * np.sin(0.3 + 0.2 * np.sin(2 * t)) + 0.05 * np.sin(40 * t)])


def test_winter_anthropometry_gives_the_knee_model_its_inertia_mass_and_centre_of_mass() -> None:
    seg, m = 0.246 * 1.75, 0.061 * 75.0
    assert KNEE.mass == pytest.approx(m)
    assert KNEE.com == pytest.approx(0.606 * seg)
    assert KNEE.inertia == pytest.approx(m * seg**2 * (0.416**2 + 0.606**2))
    assert KNEE.beta == pytest.approx(m * G * 0.606 * seg / KNEE.inertia)
    assert (KNEE.phi0, KNEE.d[0], KNEE.c[3], KNEE.theta_eq) == (0.40, 4.05, 0.28, 0.13)  # Table 1, P1-L


@pytest.mark.parametrize("params", [KNEE, LINKS])
def test_sdc_form_reproduces_the_dynamics_and_measurements(params: KneeParams | TwoLinkParams) -> None:
    rng = np.random.default_rng(3)
    n = 2 if isinstance(params, KneeParams) else 4
    for _ in range(20):
        x = rng.uniform(-0.8, 0.8, n) + (0.8 if n == 2 else 0.0)
        u = rng.uniform(0, 0.3, 1 if n == 2 else 2)
        f, h, _a, c = params.model(x, u, jacobian=False)
        fj, _hj, jf, _jh = params.model(x, u, jacobian=True)
        np.testing.assert_allclose(f, fj)
        np.testing.assert_allclose(c @ x, h)
        np.testing.assert_allclose(h[-n // 2 :], -G * np.sin(x[: n // 2]), rtol=1e-12)
        # the Jacobian against central differences of f
        for j in range(n):
            e = np.zeros(n)
            e[j] = 1e-6
            col = (params.model(x + e, u, False)[0] - params.model(x - e, u, False)[0]) / 2e-6
            np.testing.assert_allclose(jf[:, j], col, rtol=1e-5, atol=1e-5)


def test_sinc_coefficients_at_zero_angle_are_finite_and_match_the_limit() -> None:
    _, _, a, c = KNEE.model(np.zeros(2), np.zeros(1), False)
    assert a[1, 0] == pytest.approx(-KNEE.beta) and c[1, 0] == pytest.approx(-G)


@pytest.mark.parametrize("jacobian", [False, True])
def test_sdre_and_ekf_follow_a_direct_integration_of_their_riccati_equation(jacobian: bool) -> None:
    """The joint estimate and Riccati ODE (eqs. 4.14-4.16), input held per sample, by solve_ivp."""
    dt, n = 0.01, 60
    y = _measurements(n, dt)
    u = np.full(n, 0.1)
    q, s = np.array([1e-3, 1e-1]), np.array([1e-1, 1.0])
    est = ContinuousFilter(KNEE, q, s, jacobian=jacobian, max_step=1e-3)
    out = est.run(y, u, dt, [0.3, 0.0])
    a = 0.0 if jacobian else 1.0

    def rhs(_t: float, z: np.ndarray, yk: np.ndarray, uk: float) -> np.ndarray:
        x, p = z[:2], z[2:].reshape(2, 2)
        f, h, am, cm = KNEE.model(x, np.array([uk]), jacobian)
        k = p @ cm.T @ np.diag(1 / s)
        dp = am @ p + p @ am.T + 2 * a * p - p @ cm.T @ np.diag(1 / s) @ cm @ p + np.diag(q)
        return np.concatenate([f + k @ (yk - h), dp.ravel()])

    z = np.concatenate([[0.3, 0.0], np.eye(2).ravel()])
    for k in range(1, n):
        z = solve_ivp(rhs, (0, dt), z, args=(y[k], u[k]), rtol=1e-11, atol=1e-12, method="DOP853").y[:, -1]
        np.testing.assert_allclose(out[k], z[:2], atol=1e-6)  # RK4 at 1 ms
    np.testing.assert_allclose(est.P, z[2:].reshape(2, 2), atol=1e-6)
    np.testing.assert_allclose(est.P, est.P.T)


@pytest.mark.parametrize("params", [KNEE, LINKS])
@pytest.mark.parametrize("jacobian", [False, True])
def test_compiled_kernel_matches_the_numpy_reference(params: KneeParams | TwoLinkParams, jacobian: bool) -> None:
    dt, n = 0.01, 80
    y2 = _measurements(n, dt)
    if isinstance(params, KneeParams):
        y, u, x0, q = y2, np.full((n, 1), 0.1), [0.3, 0.0], [1e-3, 1e-1]
    else:
        y = np.column_stack([y2[:, 0], 0.5 * y2[:, 0], y2[:, 1], y2[:, 1]])
        u, x0, q = np.tile([2.0, 1.0], (n, 1)), [0.3, 0.2, 0.0, 0.0], [1e-3, 1e-3, 1e-1, 1e-1]
    s = np.full(len(x0), 1e-4)  # small S: stiff, so the steps shorten
    fast = ContinuousFilter(params, q, s, jacobian=jacobian)
    slow = ContinuousFilter(params, q, s, jacobian=jacobian, compiled=False)
    np.testing.assert_allclose(fast.run(y, u, dt, x0), slow.run(y, u, dt, x0), atol=1e-10)
    np.testing.assert_allclose(fast.P, slow.P, atol=1e-10)
    assert np.all(np.isfinite(fast.P))


@pytest.mark.parametrize("passive_knee", [False, True])
def test_two_link_fast_path_equals_the_generic_kernel_on_a_walking_trial(passive_knee: bool) -> None:
    """Issue #24: the two-link SDRE's specialised RK4 (what ``sdre_knee`` runs) against today's generic
    kernel (:func:`rk4`, kept as the reference), sample by sample from the same start, on a simulated walk
    with a speed and an incline change; the default stack estimator's tuning (no passive torque) and
    the knee's passive torque (the exponentials' branch)."""
    from gaitscope.estimators import _sdre_kernel as kernel
    from gaitscope.sessions.schema import REPLAY_TIME
    from gaitscope.sessions.synth.trials import sensor_trial

    sensors, leg, mass = sensor_trial([(1.2, 0.0, 6), (0.9, 6.0, 6)], subject=2)
    est = SDREKnee(leg, mass)
    f = est.filter
    if passive_knee:
        f = ContinuousFilter(TwoLinkParams.from_anthropometry(leg / 0.53, mass, KNEE), np.diag(f.q), 1 / f.sinv)
    col = {c: sensors[c].to_numpy() for c in est.inputs}
    ys = np.column_stack(
        [
            np.radians(col["imu_thigh_gyro_z_dps"]),
            np.radians(col["imu_shank_gyro_z_dps"]),
            -col["imu_thigh_accel_x_m_s2"],
            -col["imu_shank_accel_x_m_s2"],
        ]
    )
    dt, u = float(np.diff(sensors[REPLAY_TIME].to_numpy()).mean()), np.zeros(2)
    x0 = np.array([math.asin(-ys[0, 2] / G), math.asin(-ys[0, 3] / G), ys[0, 0], ys[0, 1]])
    x, pm, x_ref, p_ref = x0.copy(), f.p0.copy(), x0.copy(), f.p0.copy()
    worst, steps = 0.0, 0
    for k in range(1, ys.shape[0]):
        n = kernel.integrate(2, f._p, f.a, False, x, pm, f.q, f.sinv, ys[k], u, dt, 10)
        n_ref = kernel.substeps_for(2, f._p, f.a, False, x_ref, p_ref, f.sinv, u, dt, 10)
        kernel.rk4(2, f._p, f.a, False, x_ref, p_ref, f.q, f.sinv, ys[k], u, dt / n_ref, n_ref)
        assert n == n_ref
        steps += n
        worst = max(worst, float(np.abs(x - x_ref).max()), float(np.abs(pm - p_ref).max()))
    assert ys.shape[0] > 1000 and steps > 20 * ys.shape[0]  # realistic: the stiff bound shortens the steps
    assert np.all(np.isfinite(x)) and np.all(np.isfinite(pm))
    assert worst <= 1e-9  # in practice 0: the same operations on the same values


def test_sdre_tracks_a_simulated_seated_knee_from_a_wrong_start() -> None:
    from gaitscope.sessions.synth.fes_leg import seated_trial

    tr = seated_trial("P2-L", 5, duration_s=12.0)
    y = np.column_stack([np.radians(tr.gyro[:, 1, 2]), -tr.accel[:, 1, 0]])
    y = np.column_stack([np.interp(tr.t, tr.t_imu, y[:, 0]), np.interp(tr.t, tr.t_imu, y[:, 1])])
    est = ContinuousFilter(tr.params, [1e-4, 1e-1], [1e-4, 1e-2])
    x = est.run(y, tr.u, 1e-3, [0.0, 0.0])  # truth starts near 0.3 rad
    knee = np.degrees(math.pi / 2 - x[:, 0])
    late = tr.t > 2.0
    assert np.sqrt(np.mean((knee[late] - tr.knee_deg[late]) ** 2)) < 2.0


def test_initial_angle_inverts_the_resting_accelerometer() -> None:
    assert initial_angle(np.full(10, -G * math.sin(0.4))) == pytest.approx(0.4)
    assert initial_angle([-2 * G]) == pytest.approx(math.pi / 2)  # clipped


def test_rotation_matrix_method_by_hand() -> None:
    rt, rs = rotation_z(math.radians(30.0)), rotation_z(math.radians(-20.0))
    assert float(rmx_knee_angle(rt, rs)) == pytest.approx(50.0)  # thigh 30 forward, shank 20 back
    # the relative rotation ignores a common rotation of both frames (a shared frame of reference)
    common = rotation_z(0.7)
    assert float(rmx_knee_angle(common @ rt, common @ rs)) == pytest.approx(50.0)
    np.testing.assert_allclose(rmx_knee_angle(rotation_z([0.1, 0.2]), rotation_z([0.0, 0.0])), np.degrees([0.1, 0.2]))


def test_complementary_angle_at_rest_reads_the_tilt_and_integrates_the_gyro() -> None:
    a = math.radians(25.0)
    n = 50
    out = complementary_angle(np.zeros(n), np.full(n, G * math.sin(a)), np.full(n, G * math.cos(a)), 0.01)
    np.testing.assert_allclose(out, 25.0)
    # a pure rotation with a consistent tilt: exactly the angle
    t = np.arange(n) * 0.01
    ang = 10.0 * t
    out = complementary_angle(np.full(n, 10.0), G * np.sin(np.radians(ang)), G * np.cos(np.radians(ang)), 0.01)
    np.testing.assert_allclose(out[1:], ang[1:], atol=1e-9)


def _still(angle_thigh: float, angle_shank: float) -> np.ndarray:
    return np.array([0.0, G * math.sin(math.radians(angle_thigh)), 0.0, G * math.sin(math.radians(angle_shank))])


def test_stack_estimator_implements_the_interface_and_reads_a_still_leg() -> None:
    est = SDREKnee(0.9, 70.0)
    assert isinstance(est, Estimator)
    for k in range(300):
        out = est.step(k * 0.01, _still(20.0, -10.0))
    # the hanging-leg model (u = 0) pulls a still leg held off the vertical toward hanging: biased, bounded
    assert 15.0 < out[0] < 30.0 and 10.0 < out[1] <= 20.0
    held = est.step(3.0, np.array([np.nan, 1.0, 0.0, 0.0]))
    np.testing.assert_array_equal(held, out)
    with pytest.raises(TypeError):
        est.retune(nope=1.0)
    with pytest.raises(ValueError):
        est.retune(q_rate=-1.0)
    est.reset()
    for k in range(100):
        out = est.step(k * 0.01, _still(0.0, 0.0))
    np.testing.assert_allclose(out, [0.0, 0.0], atol=1e-9)  # hanging still: the model's equilibrium


finite_or_not = st.one_of(
    st.floats(min_value=-1e6, max_value=1e6), st.sampled_from([math.nan, math.inf, -math.inf, 1e300])
)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(finite_or_not, finite_or_not, finite_or_not, finite_or_not), min_size=1, max_size=25))
def test_stack_estimator_never_returns_a_non_finite_output(samples: list[tuple[float, ...]]) -> None:
    est = SDREKnee(0.9)
    for k, z in enumerate(samples):
        out = est.step(0.01 * k, np.array(z, dtype=np.float64))
        assert out.shape == (2,) and np.all(np.isfinite(out))

"""Compiled integration of the SDRE estimator and its EKF comparator (numba). Private: use :mod:`estimators.sdre`.

The same maths as :class:`gaitscope.estimators.sdre.ContinuousFilter` (numpy, the test oracle) written as scalar
loops: the joint ODE of the estimate and its Riccati matrix,

    xhat' = f(xhat, u) + K (y - h(xhat)),  K = P Cm^T S^-1,
    P'    = Am P + P Am^T + 2 a P - K Cm P + Q,

with ``(Am, Cm)`` the SDC pair ``(A(xhat), C(xhat))`` (SDRE) or the Jacobians of ``f`` and ``h`` (EKF),
integrated by classic RK4 with ``y`` and ``u`` held over the step, ``P`` symmetrised after each step; a
step is shortened below the requested one where the equations are stiff (a small ``S`` with a large ``P``
makes the Riccati equation's rate ``g^2 P / S`` reach 10^6 /s), see :func:`integrate`.
``A(x) x + B(x) u = f(x, u)`` and ``C(x) x = h(x)`` exactly for both models, so the estimate's equation
is written with ``f`` and ``h``. ``S`` is diagonal (the thesis's eq. 4.17): ``sinv`` holds its inverse's
diagonal.

Models (``model``): 1, the seated knee (eqs. 4.6-4.7, 4.11-4.13), ``p`` = ``[alpha, beta, g, phi0, d1..d6,
c0..c3]``, ``u`` = ``[u_ke]``; 2, the fixed-hip thigh and shank (eqs. 4.23-4.25), ``p`` = ``[m11, m22, a1,
b2, b3, g, phi0, d1..d6]``, ``u`` = ``[hip torque, knee torque]`` (N m, the known active joint torques).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from gaitscope.estimators.basis import Array


@njit(cache=True)
def sinc(x: float) -> float:
    """``sin(x) / x``, 1 at 0 (the thesis's unnormalised sinc)."""
    if abs(x) < 1e-8:
        return 1.0 - x * x / 6.0
    return math.sin(x) / x


@njit(cache=True)
def knee_torques(p: Array, phi: float, phidot: float, u: float) -> float:
    """``T_p + T_ke`` of the seated knee (eqs. 4.2-4.3) at knee angle ``phi``, rate ``phidot`` (rad, rad/s)."""
    tp = p[4] * (phi - p[3]) + p[5] * phidot + p[6] * math.exp(p[7] * phi) - p[8] * math.exp(p[9] * phi)
    tke = (p[12] * phi * phi + p[11] * phi + p[10]) * (1.0 + p[13] * phidot) * u
    return tp + tke


@njit(cache=True)
def two_link_rhs(p: Array, x: Array, u: Array) -> tuple[float, float]:
    """The fixed-hip model's accelerations ``M^-1 (-V - G + T_pa + T)`` (eq. 4.23)."""
    m11, m22, a1, b2, b3 = p[0], p[1], p[2], p[3], p[4]
    d = x[0] - x[1]
    s, c = math.sin(d), math.cos(d)
    phi, phidot = d, x[2] - x[3]  # knee flexion: thigh minus shank
    tk = p[7] * (phi - p[6]) + p[8] * phidot + p[9] * math.exp(p[10] * phi) - p[11] * math.exp(p[12] * phi)
    # passive knee torque ``tk`` extends the knee (raises the shank's angle): generalised force [-tk, tk]
    r1 = -a1 * x[3] * x[3] * s - b2 * math.sin(x[0]) + u[0] - u[1] - tk
    r2 = a1 * x[2] * x[2] * s - b3 * math.sin(x[1]) + u[1] + tk
    det = m11 * m22 - a1 * a1 * c * c
    return (m22 * r1 - a1 * c * r2) / det, (-a1 * c * r1 + m11 * r2) / det


@njit(cache=True)
def evaluate(model: int, p: Array, x: Array, u: Array, jac: bool, f: Array, h: Array, am: Array, cm: Array) -> None:
    """Fill ``f(x, u)``, ``h(x)`` and the pair ``(Am, Cm)``: SDC (``jac`` False) or Jacobians (True)."""
    am[:, :] = 0.0
    cm[:, :] = 0.0
    if model == 1:
        alpha, beta, g = p[0], p[1], p[2]
        phi, phidot = math.pi / 2 - x[0], -x[1]
        f[0] = x[1]
        f[1] = -beta * math.sin(x[0]) + alpha * knee_torques(p, phi, phidot, u[0])
        h[0] = x[1]
        h[1] = -g * math.sin(x[0])
        am[0, 1] = 1.0
        cm[0, 1] = 1.0
        if jac:
            uu = u[0]
            dtp_dphi = p[4] + p[6] * p[7] * math.exp(p[7] * phi) - p[8] * p[9] * math.exp(p[9] * phi)
            dtke_dphi = (2.0 * p[12] * phi + p[11]) * (1.0 + p[13] * phidot) * uu
            dtke_dphidot = (p[12] * phi * phi + p[11] * phi + p[10]) * p[13] * uu
            am[1, 0] = -beta * math.cos(x[0]) - alpha * (dtp_dphi + dtke_dphi)
            am[1, 1] = -alpha * (p[5] + dtke_dphidot)
            cm[1, 0] = -g * math.cos(x[0])
        else:
            am[1, 0] = -beta * sinc(x[0])
            cm[1, 0] = -g * sinc(x[0])
        return
    # model 2: the fixed-hip thigh and shank
    m11, m22, a1, b2, b3, g = p[0], p[1], p[2], p[3], p[4], p[5]
    acc = two_link_rhs(p, x, u)
    f[0], f[1], f[2], f[3] = x[2], x[3], acc[0], acc[1]
    h[0], h[1] = x[2], x[3]
    h[2], h[3] = -g * math.sin(x[0]), -g * math.sin(x[1])
    am[0, 2] = 1.0
    am[1, 3] = 1.0
    cm[0, 2] = 1.0
    cm[1, 3] = 1.0
    if jac:
        cm[2, 0] = -g * math.cos(x[0])
        cm[3, 1] = -g * math.cos(x[1])
        xp = x.copy()
        for j in range(4):  # central differences of the accelerations (documented in gaitscope.estimators.sdre)
            step = 1e-6 * max(1.0, abs(x[j]))
            xp[j] = x[j] + step
            hi = two_link_rhs(p, xp, u)
            xp[j] = x[j] - step
            lo = two_link_rhs(p, xp, u)
            xp[j] = x[j]
            am[2, j] = (hi[0] - lo[0]) / (2 * step)
            am[3, j] = (hi[1] - lo[1]) / (2 * step)
        return
    d = x[0] - x[1]
    s, c = math.sin(d), math.cos(d)
    det = m11 * m22 - a1 * a1 * c * c
    w11, w12, w21, w22 = m22 / det, -a1 * c / det, -a1 * c / det, m11 / det
    am[2, 0] = -w11 * b2 * sinc(x[0])
    am[2, 1] = -w12 * b3 * sinc(x[1])
    am[2, 2] = w12 * a1 * x[2] * s
    am[2, 3] = -w11 * a1 * x[3] * s
    am[3, 0] = -w21 * b2 * sinc(x[0])
    am[3, 1] = -w22 * b3 * sinc(x[1])
    am[3, 2] = w22 * a1 * x[2] * s
    am[3, 3] = -w21 * a1 * x[3] * s
    cm[2, 0] = -g * sinc(x[0])
    cm[3, 1] = -g * sinc(x[1])


@njit(cache=True)
def derivative(
    model: int, p: Array, a: float, jac: bool, x: Array, pm: Array, q: Array, sinv: Array, y: Array, u: Array,
    dx: Array, dp: Array,
) -> None:  # fmt: skip
    """The joint right-hand side (module docstring), into ``dx`` and ``dp``."""
    n, m = x.shape[0], y.shape[0]
    f, h = np.empty(n), np.empty(m)
    am, cm = np.empty((n, n)), np.empty((m, n))
    evaluate(model, p, x, u, jac, f, h, am, cm)
    k = np.zeros((n, m))  # P Cm^T S^-1
    for i in range(n):
        for j in range(m):
            acc = 0.0
            for l in range(n):
                acc += pm[i, l] * cm[j, l]
            k[i, j] = acc * sinv[j]
    cp = np.zeros((m, n))  # Cm P
    for i in range(m):
        for j in range(n):
            acc = 0.0
            for l in range(n):
                acc += cm[i, l] * pm[l, j]
            cp[i, j] = acc
    for i in range(n):
        acc = f[i]
        for j in range(m):
            acc += k[i, j] * (y[j] - h[j])
        dx[i] = acc
        for j in range(n):
            acc = q[i, j] + 2.0 * a * pm[i, j]
            for l in range(n):
                acc += am[i, l] * pm[l, j] + pm[i, l] * am[j, l]
            for l in range(m):
                acc -= k[i, l] * cp[l, j]
            dp[i, j] = acc


@njit(cache=True)
def stiffness(model: int, p: Array, a: float, jac: bool, x: Array, pm: Array, sinv: Array, u: Array) -> float:
    """A bound on the joint ODE's fastest rate (1/s): ``2 (||Am - K Cm||_inf + |a|)``, the error dynamics'
    row-sum bound, doubled for the Riccati equation (``P`` evolves with it on both sides)."""
    n, m = x.shape[0], sinv.shape[0]
    f, h = np.empty(n), np.empty(m)
    am, cm = np.empty((n, n)), np.empty((m, n))
    evaluate(model, p, x, u, jac, f, h, am, cm)
    worst = 0.0
    for i in range(n):
        row = 0.0
        for j in range(n):
            kc = 0.0
            for l in range(m):
                kp = 0.0
                for r in range(n):
                    kp += pm[i, r] * cm[l, r]
                kc += kp * sinv[l] * cm[l, j]
            row += abs(am[i, j] - kc)
        worst = max(worst, row)
    return 2.0 * (worst + abs(a))


@njit(cache=True)
def integrate(
    model: int, p: Array, a: float, jac: bool, x: Array, pm: Array, q: Array, sinv: Array, y: Array, u: Array,
    dt: float, substeps: int,
) -> int:  # fmt: skip
    """Advance ``x`` and ``pm`` in place by ``dt`` in at least ``substeps`` equal RK4 steps, ``y`` and ``u``
    held; more where the system is stiff, so that a step times :func:`stiffness` stays within 0.5 (well
    inside RK4's stability region, which reaches -2.78 on the real axis, and accurate to about 1e-4 of
    the fast transient per step). Returns the number of steps taken."""
    n = x.shape[0]
    rate = stiffness(model, p, a, jac, x, pm, sinv, u)
    if rate * dt / substeps > 0.5:
        substeps = min(math.ceil(rate * dt / 0.5), 100000)
    hstep = dt / substeps
    k1x, k2x, k3x, k4x = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    k1p, k2p, k3p, k4p = np.empty((n, n)), np.empty((n, n)), np.empty((n, n)), np.empty((n, n))
    for _ in range(substeps):
        derivative(model, p, a, jac, x, pm, q, sinv, y, u, k1x, k1p)
        derivative(model, p, a, jac, x + 0.5 * hstep * k1x, pm + 0.5 * hstep * k1p, q, sinv, y, u, k2x, k2p)
        derivative(model, p, a, jac, x + 0.5 * hstep * k2x, pm + 0.5 * hstep * k2p, q, sinv, y, u, k3x, k3p)
        derivative(model, p, a, jac, x + hstep * k3x, pm + hstep * k3p, q, sinv, y, u, k4x, k4p)
        x += hstep / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x)
        pm += hstep / 6.0 * (k1p + 2.0 * k2p + 2.0 * k3p + k4p)
        for i in range(n):
            for j in range(i + 1, n):
                s = 0.5 * (pm[i, j] + pm[j, i])
                pm[i, j] = s
                pm[j, i] = s
    return substeps


@njit(cache=True)
def run(
    model: int, p: Array, a: float, jac: bool, x0: Array, p0: Array, q: Array, sinv: Array, ys: Array, us: Array,
    dt: float, substeps: int,
) -> Array:  # fmt: skip
    """Estimates at every sample: row 0 is ``x0``; row ``k`` integrates over ``dt`` holding sample ``k``.
    ``x0`` and ``p0`` end as the last estimate and Riccati matrix."""
    out = np.empty((ys.shape[0], x0.shape[0]))
    x, pm = x0, p0
    out[0] = x
    for k in range(1, ys.shape[0]):
        integrate(model, p, a, jac, x, pm, q, sinv, ys[k], us[k], dt, substeps)
        out[k] = x
    return out

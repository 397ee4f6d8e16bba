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
def substeps_for(
    model: int, p: Array, a: float, jac: bool, x: Array, pm: Array, sinv: Array, u: Array, dt: float, substeps: int
) -> int:
    """The RK4 steps :func:`integrate` takes over ``dt``: at least ``substeps``, more where the system is stiff,
    so that a step times :func:`stiffness` stays within 0.5 (well inside RK4's stability region, which
    reaches -2.78 on the real axis, and accurate to about 1e-4 of the fast transient per step)."""
    rate = stiffness(model, p, a, jac, x, pm, sinv, u)
    if rate * dt / substeps > 0.5:
        substeps = min(math.ceil(rate * dt / 0.5), 100000)
    return substeps


@njit(cache=True)
def integrate(
    model: int, p: Array, a: float, jac: bool, x: Array, pm: Array, q: Array, sinv: Array, y: Array, u: Array,
    dt: float, substeps: int,
) -> int:  # fmt: skip
    """Advance ``x`` and ``pm`` in place by ``dt`` in :func:`substeps_for` equal RK4 steps, ``y`` and ``u``
    held: the two-link SDRE by :func:`two_link_sdre_rk4`, everything else by :func:`rk4`. Returns the number
    of steps taken."""
    substeps = substeps_for(model, p, a, jac, x, pm, sinv, u, dt, substeps)
    if model == 2 and not jac:
        two_link_sdre_rk4(p, a, x, pm, q, sinv, y, u, dt / substeps, substeps)
    else:
        rk4(model, p, a, jac, x, pm, q, sinv, y, u, dt / substeps, substeps)
    return substeps


@njit(cache=True)
def rk4(
    model: int, p: Array, a: float, jac: bool, x: Array, pm: Array, q: Array, sinv: Array, y: Array, u: Array,
    hstep: float, substeps: int,
) -> None:  # fmt: skip
    """``substeps`` classic RK4 steps of ``hstep`` on :func:`derivative`, ``P`` symmetrised after each: any model,
    SDC pair or Jacobians, and the reference :func:`two_link_sdre_rk4` is checked against."""
    n = x.shape[0]
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


@njit(cache=True)
def two_link_sdre_rk4(
    p: Array, a: float, x: Array, pm: Array, q: Array, sinv: Array, y: Array, u: Array, hstep: float, substeps: int
) -> None:
    """:func:`rk4` of the two-link SDRE (model 2, SDC pair), value for value: the same operations on the same
    operands in the same order, without the work whose result is known or the allocations. Per step,
    :func:`derivative` is written out in the stage loop (a function call, inlined or not, cost a fifth
    more: numba counts references to the arrays it is passed), on workspace allocated once;
    :func:`evaluate`'s :func:`two_link_rhs` and SDC rows share their sines, cosine and ``det`` (they
    recompute the same expressions); the passive torque's exponentials are skipped when ``d3..d6`` are
    all 0 (each term is ``0 * exp(0)``, exactly 0); products with the structural zeros of ``Cm`` (rows
    ``e3, e4, [c20, 0, 0, 0], [0, c31, 0, 0]``) and of ``Am``'s first two rows (``e3, e4``) are left
    out, and those with their ones taken as the factor itself. Adding an exact zero changes no finite
    sum, so for finite values the result is :func:`rk4`'s (a signed zero aside; checked sample by sample
    in ``tests/estimators/test_sdre.py``), about 7x faster. Issue #24."""
    m11, m22, a1, b2, b3, g = p[0], p[1], p[2], p[3], p[4], p[5]
    exps = p[9] != 0.0 or p[10] != 0.0 or p[11] != 0.0 or p[12] != 0.0
    kx, kp = np.empty((4, 4)), np.empty((4, 4, 4))  # the four stages' derivatives
    xs, ps, am = np.empty(4), np.empty((4, 4)), np.empty((2, 4))  # a stage's point; Am's last two rows
    half = 0.5 * hstep
    for _ in range(substeps):
        for stage in range(4):  # the stage's point, then the derivative there (eqs. 4.14-4.16, 4.23-4.25)
            if stage == 0:
                for i in range(4):
                    xs[i] = x[i]
                    for j in range(4):
                        ps[i, j] = pm[i, j]
            else:
                w = hstep if stage == 3 else half
                for i in range(4):
                    xs[i] = x[i] + w * kx[stage - 1, i]
                    for j in range(4):
                        ps[i, j] = pm[i, j] + w * kp[stage - 1, i, j]
            x0, x1, x2, x3 = xs[0], xs[1], xs[2], xs[3]
            d = x0 - x1
            s, c = math.sin(d), math.cos(d)
            sin0, sin1 = math.sin(x0), math.sin(x1)
            tk = p[7] * (d - p[6]) + p[8] * (x2 - x3)
            if exps:
                tk = tk + p[9] * math.exp(p[10] * d) - p[11] * math.exp(p[12] * d)
            r1 = -a1 * x3 * x3 * s - b2 * sin0 + u[0] - u[1] - tk
            r2 = a1 * x2 * x2 * s - b3 * sin1 + u[1] + tk
            det = m11 * m22 - a1 * a1 * c * c
            f2 = (m22 * r1 - a1 * c * r2) / det
            f3 = (-a1 * c * r1 + m11 * r2) / det
            sinc0 = 1.0 - x0 * x0 / 6.0 if abs(x0) < 1e-8 else sin0 / x0  # sinc(), the sine already taken
            sinc1 = 1.0 - x1 * x1 / 6.0 if abs(x1) < 1e-8 else sin1 / x1
            w11, w12, w22 = m22 / det, -a1 * c / det, m11 / det
            w21 = w12
            am[0, 0], am[0, 1] = -w11 * b2 * sinc0, -w12 * b3 * sinc1
            am[0, 2], am[0, 3] = w12 * a1 * x2 * s, -w11 * a1 * x3 * s
            am[1, 0], am[1, 1] = -w21 * b2 * sinc0, -w22 * b3 * sinc1
            am[1, 2], am[1, 3] = w22 * a1 * x2 * s, -w21 * a1 * x3 * s
            c20, c31 = -g * sinc0, -g * sinc1
            e0, e1, e2, e3 = y[0] - x2, y[1] - x3, y[2] - -g * sin0, y[3] - -g * sin1  # y - h
            for i in range(4):
                # row i of K = P Cm^T S^-1
                k0, k1 = ps[i, 2] * sinv[0], ps[i, 3] * sinv[1]
                k2, k3 = ps[i, 0] * c20 * sinv[2], ps[i, 1] * c31 * sinv[3]
                fi = x2 if i == 0 else x3 if i == 1 else f2 if i == 2 else f3
                kx[stage, i] = fi + k0 * e0 + k1 * e1 + k2 * e2 + k3 * e3
                for j in range(4):
                    acc = q[i, j] + 2.0 * a * ps[i, j]
                    # + (Am P + P Am^T)[i, j], term by term; Am's rows 0 and 1 are e3 and e4
                    for l in range(4):
                        zero_i, zero_j = i < 2 and l != i + 2, j < 2 and l != j + 2  # Am[i, l], Am[j, l] are 0
                        a_il = 1.0 if i < 2 else am[i - 2, l]
                        a_jl = 1.0 if j < 2 else am[j - 2, l]
                        if zero_i and zero_j:
                            continue
                        if zero_i:
                            acc += ps[i, l] * a_jl
                        elif zero_j:
                            acc += a_il * ps[l, j]
                        else:
                            acc += a_il * ps[l, j] + ps[i, l] * a_jl
                    # - (K Cm P)[i, j]; Cm P's rows are P's rows 2 and 3, c20 P's row 0, c31 P's row 1
                    acc -= k0 * ps[2, j]
                    acc -= k1 * ps[3, j]
                    acc -= k2 * (c20 * ps[0, j])
                    acc -= k3 * (c31 * ps[1, j])
                    kp[stage, i, j] = acc
        sixth = hstep / 6.0
        for i in range(4):
            x[i] += sixth * (kx[0, i] + 2.0 * kx[1, i] + 2.0 * kx[2, i] + kx[3, i])
            for j in range(4):
                pm[i, j] += sixth * (kp[0, i, j] + 2.0 * kp[1, i, j] + 2.0 * kp[2, i, j] + kp[3, i, j])
        for i in range(4):
            for j in range(i + 1, 4):
                mean = 0.5 * (pm[i, j] + pm[j, i])
                pm[i, j] = mean
                pm[j, i] = mean


@njit(cache=True)
def healthy(x: Array, pm: Array, bound: float) -> bool:
    """Every entry of ``x`` and ``pm`` finite and the angles (``x``'s first half) within ``+/- bound``."""
    n = x.shape[0]
    for i in range(n):
        if not math.isfinite(x[i]):
            return False
        for j in range(n):
            if not math.isfinite(pm[i, j]):
                return False
    for i in range(n // 2):
        if not abs(x[i]) < bound:
            return False
    return True


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

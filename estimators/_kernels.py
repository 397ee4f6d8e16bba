"""Compiled inner loops of the phase EKF (numba). Private: use :mod:`estimators.phase_ekf`.

Each function is the plain-numpy maths of seed 000 section II-C written as scalar loops so that numba
turns one filter step into a few microseconds. The filterpy-based reference in
:mod:`estimators.reference` computes the same quantities with vectorised numpy and is the test oracle.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from estimators.basis import Array

_PI4 = np.pi / 4.0


@njit(cache=True)
def stride_from_pseudo(lp: float) -> tuple[float, float]:
    """``l/L = (4/pi) atan(pi lp / 4) + 2`` and its derivative (seed 000 eq. 15)."""
    u = _PI4 * lp
    return np.arctan(u) / _PI4 + 2.0, 1.0 / (1.0 + u * u)


@njit(cache=True)
def model_terms(coef: Array, p: float, l: float, r: float, out: Array) -> None:
    """Fill ``out[o] = [h, h_p, h_pp, h_l, h_r, h_pl, h_pr]`` for each output o of the gait model.

    Args:
        coef: ``(n_out, 2, 2, K)`` coefficients, K = 2N + 1.
        p, l, r: phase, normalised stride length, incline (deg).
        out: ``(n_out, 7)`` written in place.
    """
    K = coef.shape[3]
    order = (K - 1) // 2
    lam0 = np.empty(K)
    lam1 = np.empty(K)
    lam2 = np.empty(K)
    lam0[0], lam1[0], lam2[0] = 1.0, 0.0, 0.0
    w1 = 2.0 * np.pi
    c1, s1 = np.cos(w1 * p), np.sin(w1 * p)
    c, s = 1.0, 0.0
    for k in range(1, order + 1):
        c, s = c * c1 - s * s1, s * c1 + c * s1  # angle addition: cos/sin of 2 pi k p
        w = w1 * k
        lam0[2 * k - 1], lam0[2 * k] = c, s
        lam1[2 * k - 1], lam1[2 * k] = -w * s, w * c
        lam2[2 * k - 1], lam2[2 * k] = -w * w * c, -w * w * s
    lr0, lr1 = r, 1.0 - r
    ll0, ll1 = l, 1.0 - l
    for o in range(coef.shape[0]):
        a = np.zeros((2, 2))
        a1 = np.zeros((2, 2))
        a2 = np.zeros((2, 2))
        for i in range(2):
            for j in range(2):
                s0 = 0.0
                s1_ = 0.0
                s2 = 0.0
                for m in range(K):
                    cm = coef[o, i, j, m]
                    s0 += cm * lam0[m]
                    s1_ += cm * lam1[m]
                    s2 += cm * lam2[m]
                a[i, j], a1[i, j], a2[i, j] = s0, s1_, s2
        out[o, 0] = lr0 * (ll0 * a[0, 0] + ll1 * a[0, 1]) + lr1 * (ll0 * a[1, 0] + ll1 * a[1, 1])
        out[o, 1] = lr0 * (ll0 * a1[0, 0] + ll1 * a1[0, 1]) + lr1 * (ll0 * a1[1, 0] + ll1 * a1[1, 1])
        out[o, 2] = lr0 * (ll0 * a2[0, 0] + ll1 * a2[0, 1]) + lr1 * (ll0 * a2[1, 0] + ll1 * a2[1, 1])
        out[o, 3] = lr0 * (a[0, 0] - a[0, 1]) + lr1 * (a[1, 0] - a[1, 1])
        out[o, 4] = (ll0 * a[0, 0] + ll1 * a[0, 1]) - (ll0 * a[1, 0] + ll1 * a[1, 1])
        out[o, 5] = lr0 * (a1[0, 0] - a1[0, 1]) + lr1 * (a1[1, 0] - a1[1, 1])
        out[o, 6] = (ll0 * a1[0, 0] + ll1 * a1[0, 1]) - (ll0 * a1[1, 0] + ll1 * a1[1, 1])


@njit(cache=True)
def measurement(coef: Array, x: Array, leg_length: float, terms: Array, h: Array, H: Array) -> None:
    """Predicted measurement ``h(x)`` (6,) and Jacobian ``H`` (6, 4) of seed 000 eq. 16-17.

    Channels: foot angle, foot velocity, shank angle, shank velocity (deg, deg/s), heel forward and
    heel up (m; the model is in leg lengths). State ``x = [p, pdot, lp, r]``.
    """
    p, pdot, lp, r = x[0], x[1], x[2], x[3]
    l, dl = stride_from_pseudo(lp)
    model_terms(coef, p, l, r, terms)
    for a in range(2):  # foot, shank: angle and velocity rows
        t = terms[a]
        ia, iv = 2 * a, 2 * a + 1
        h[ia] = t[0]
        H[ia, 0], H[ia, 1], H[ia, 2], H[ia, 3] = t[1], 0.0, t[3] * dl, t[4]
        h[iv] = pdot * t[1]
        H[iv, 0], H[iv, 1], H[iv, 2], H[iv, 3] = pdot * t[2], t[1], pdot * t[5] * dl, pdot * t[6]
    for a in range(2):  # heel forward, heel up
        t = terms[2 + a]
        i = 4 + a
        h[i] = leg_length * t[0]
        H[i, 0] = leg_length * t[1]
        H[i, 1] = 0.0
        H[i, 2] = leg_length * t[3] * dl
        H[i, 3] = leg_length * t[4]


@njit(cache=True)
def noise_at(bins: Array, p: float, out: Array) -> None:
    """``Sigma_R(p)`` interpolated linearly between phase bins ``b / B`` (periodic)."""
    B = bins.shape[0]
    u = (p - np.floor(p)) * B
    i0 = int(np.floor(u)) % B
    f = u - np.floor(u)
    i1 = (i0 + 1) % B
    for a in range(bins.shape[1]):
        for b in range(bins.shape[2]):
            out[a, b] = (1.0 - f) * bins[i0, a, b] + f * bins[i1, a, b]


@njit(cache=True)
def predict(x: Array, P: Array, dt: float, q_diag: Array) -> None:
    """Constant-phase-rate prediction in place: ``x = F x``, ``P = F P F^T + Q`` (seed 000 eq. 13-14)."""
    x[0] = x[0] + dt * x[1]
    x[0] -= np.floor(x[0])
    # F = I + dt e0 e1^T: F P adds dt row 1 to row 0, (F P) F^T adds dt column 1 to column 0
    for j in range(4):
        P[0, j] += dt * P[1, j]
    for i in range(4):
        P[i, 0] += dt * P[i, 1]
    for i in range(4):
        P[i, i] += q_diag[i]


@njit(cache=True)
def update(
    x: Array,
    P: Array,
    z: Array,
    h: Array,
    H: Array,
    R: Array,
    y_out: Array,
    S_out: Array,
    K_out: Array,
    wrap_phase: bool,
) -> tuple[int, float, float]:
    """Kalman update with the finite entries of ``z`` only; Joseph-form covariance (as filterpy).

    ``h``, ``H`` (6, n) and ``R`` are the full 6-channel prediction, Jacobian and covariance at the
    prior, for a state of any size n. ``y_out`` (6,), ``S_out`` (6, 6) and ``K_out`` (n, 6) receive the
    innovation, its covariance and the gain on the used channels (NaN elsewhere). With ``wrap_phase``
    ``x[0]`` is wrapped into [0, 1) after the update. ``S`` is factored by Cholesky (explicit loops:
    for at most six channels they beat a LAPACK call several times over).

    Returns:
        ``(m, y^T S^-1 y, log det S)`` with m the number of channels used.
    """
    n = x.shape[0]
    idx = np.empty(6, dtype=np.int64)
    m = 0
    for i in range(6):
        if np.isfinite(z[i]):
            idx[m] = i
            m += 1
    y_out[:] = np.nan
    S_out[:] = np.nan
    K_out[:] = np.nan
    if m == 0:
        return 0, 0.0, 0.0
    y = np.empty(m)
    PHt = np.zeros((n, m))  # P H^T
    for a in range(m):
        ia = idx[a]
        y[a] = z[ia] - h[ia]
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += P[i, j] * H[ia, j]
            PHt[i, a] = acc
    S = np.empty((m, m))
    for a in range(m):
        for b in range(a, m):
            acc = R[idx[a], idx[b]]
            for j in range(n):
                acc += H[idx[a], j] * PHt[j, b]
            S[a, b] = acc
            S[b, a] = acc
    L = np.zeros((m, m))  # S = L L^T
    logdet = 0.0
    for a in range(m):
        for b in range(a + 1):
            acc = S[a, b]
            for k in range(b):
                acc -= L[a, k] * L[b, k]
            if a == b:
                L[a, a] = np.sqrt(acc)
                logdet += 2.0 * np.log(L[a, a])
            else:
                L[a, b] = acc / L[b, b]
    # K^T = S^-1 (P H^T)^T: forward then back substitution for each state component
    K = np.empty((n, m))
    w = np.empty(m)
    for i in range(n):
        for a in range(m):
            acc = PHt[i, a]
            for k in range(a):
                acc -= L[a, k] * w[k]
            w[a] = acc / L[a, a]
        for a in range(m - 1, -1, -1):
            acc = w[a]
            for k in range(a + 1, m):
                acc -= L[k, a] * K[i, k]
            K[i, a] = acc / L[a, a]
    maha2 = 0.0
    for a in range(m):
        acc = y[a]
        for k in range(a):
            acc -= L[a, k] * w[k]
        w[a] = acc / L[a, a]
        maha2 += w[a] * w[a]
    for i in range(n):
        acc = 0.0
        for a in range(m):
            acc += K[i, a] * y[a]
        x[i] += acc
    if wrap_phase:
        x[0] -= np.floor(x[0])
    # Joseph form: (I - K H) P (I - K H)^T + K R K^T
    IKH = np.eye(n)
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for a in range(m):
                acc += K[i, a] * H[idx[a], j]
            IKH[i, j] -= acc
    T = IKH @ P
    KR = np.zeros((n, m))
    for i in range(n):
        for b in range(m):
            acc = 0.0
            for a in range(m):
                acc += K[i, a] * R[idx[a], idx[b]]
            KR[i, b] = acc
    for i in range(n):
        for j in range(i, n):
            acc = 0.0
            for k in range(n):
                acc += T[i, k] * IKH[j, k]
            for b in range(m):
                acc += KR[i, b] * K[j, b]
            P[i, j] = acc
            P[j, i] = acc
    for a in range(m):
        y_out[idx[a]] = y[a]
        for b in range(m):
            S_out[idx[a], idx[b]] = S[a, b]
        for i in range(n):
            K_out[i, idx[a]] = K[i, a]
    return m, maha2, logdet


@njit(cache=True)
def weighted_sse(y: Array, R: Array) -> float:
    """``y^T R_s^-1 y`` over the finite entries of ``y`` (R_s the matching sub-matrix of R)."""
    idx = np.empty(y.shape[0], dtype=np.int64)
    m = 0
    for i in range(y.shape[0]):
        if np.isfinite(y[i]):
            idx[m] = i
            m += 1
    if m == 0:
        return 0.0
    Rs = np.empty((m, m))
    ys = np.empty(m)
    for a in range(m):
        ys[a] = y[idx[a]]
        for b in range(m):
            Rs[a, b] = R[idx[a], idx[b]]
    return float(ys @ np.linalg.solve(Rs, ys))


@njit(cache=True)
def ekf_update(
    coef: Array,
    x: Array,
    P: Array,
    z: Array,
    leg_length: float,
    bins: Array,
    terms: Array,
    h: Array,
    H: Array,
    R: Array,
    y_out: Array,
    S_out: Array,
    K_out: Array,
) -> tuple[int, float, float]:
    """Measurement, ``Sigma_R`` at the prior phase and the update in one compiled call."""
    measurement(coef, x, leg_length, terms, h, H)
    noise_at(bins, x[0], R)
    return update(x, P, z, h, H, R, y_out, S_out, K_out, True)


@njit(cache=True)
def screen(z: Array, lo: Array, hi: Array) -> int:
    """Set every finite value of ``z`` outside ``[lo, hi]`` (and every infinity) to NaN; return how many."""
    n = 0
    for i in range(z.shape[0]):
        v = z[i]
        if v != v:  # NaN: missing already
            continue
        if not (lo[i] <= v <= hi[i]):
            z[i] = np.nan
            n += 1
    return n


@njit(cache=True)
def healthy(x: Array, P: Array, min_rate: float, max_rate: float, max_abs_incline: float, max_var: float) -> bool:
    """The EKF state and covariance are finite, the phase rate and incline in range, the variances in
    ``[0, max_var]``."""
    for i in range(x.shape[0]):
        if not np.isfinite(x[i]):
            return False
        for j in range(P.shape[1]):
            if not np.isfinite(P[i, j]):
                return False
        if not (0.0 <= P[i, i] <= max_var):
            return False
    return min_rate <= x[1] <= max_rate and abs(x[3]) <= max_abs_incline

"""Compiled inner loops of the phase EKF (numba). Private: use :mod:`gaitscope.estimators.phase_ekf`.

Each function is the plain-numpy maths of seed 000 section II-C written as scalar loops so that numba
turns one filter step into a few microseconds. The filterpy-based reference in
:mod:`gaitscope.estimators.reference` computes the same quantities with vectorised numpy and is the test oracle.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit
from numpy.typing import NDArray

from gaitscope.estimators.basis import Array

_PI4 = np.pi / 4.0


@njit(cache=True)
def stride_from_pseudo(lp: float) -> tuple[float, float]:
    """``l/L = (4/pi) atan(pi lp / 4) + 2`` and its derivative (seed 000 eq. 15)."""
    u = _PI4 * lp
    return np.arctan(u) / _PI4 + 2.0, 1.0 / (1.0 + u * u)


@njit(cache=True)
def model_terms(coef: Array, p: float, l: float, r: float, out: Array, n_second: int = -1) -> None:
    """Fill ``out[o] = [h, h_p, h_pp, h_l, h_r, h_pl, h_pr]`` for each output o of the gait model.

    Args:
        coef: ``(n_out, 2, 2, K)`` coefficients, K = 2N + 1.
        p, l, r: phase, normalised stride length, incline (deg).
        out: ``(n_out, 7)`` written in place.
        n_second: only the first ``n_second`` outputs get ``h_pp`` (the others NaN; -1: all), which
            costs a third of the time; the other terms are the same either way.
    """
    K = coef.shape[3]
    order = (K - 1) // 2
    lam = np.empty((3, K))  # the Fourier basis at p and its first two phase derivatives
    lam[0, 0], lam[1, 0], lam[2, 0] = 1.0, 0.0, 0.0
    w1 = 2.0 * np.pi
    c1, s1 = np.cos(w1 * p), np.sin(w1 * p)
    c, s = 1.0, 0.0
    for k in range(1, order + 1):
        c, s = c * c1 - s * s1, s * c1 + c * s1  # angle addition: cos/sin of 2 pi k p
        w = w1 * k
        lam[0, 2 * k - 1], lam[0, 2 * k] = c, s
        lam[1, 2 * k - 1], lam[1, 2 * k] = -w * s, w * c
        lam[2, 2 * k - 1], lam[2, 2 * k] = -w * w * c, -w * w * s
    lr0, lr1 = r, 1.0 - r
    ll0, ll1 = l, 1.0 - l
    for o in range(coef.shape[0]):
        # a_ij = sum_m coef[o, i, j, m] lam[0, m] and its phase derivatives d_ij, e_ij: twelve sums in
        # one pass, so that they overlap instead of waiting for each other's additions
        a00 = a01 = a10 = a11 = 0.0
        d00 = d01 = d10 = d11 = 0.0
        e00 = e01 = e10 = e11 = 0.0
        if n_second < 0 or o < n_second:
            for m in range(K):
                l0, l1, l2 = lam[0, m], lam[1, m], lam[2, m]
                c00, c01, c10, c11 = coef[o, 0, 0, m], coef[o, 0, 1, m], coef[o, 1, 0, m], coef[o, 1, 1, m]
                a00 += c00 * l0
                d00 += c00 * l1
                e00 += c00 * l2
                a01 += c01 * l0
                d01 += c01 * l1
                e01 += c01 * l2
                a10 += c10 * l0
                d10 += c10 * l1
                e10 += c10 * l2
                a11 += c11 * l0
                d11 += c11 * l1
                e11 += c11 * l2
        else:  # the same sums without the second derivative
            for m in range(K):
                l0, l1 = lam[0, m], lam[1, m]
                c00, c01, c10, c11 = coef[o, 0, 0, m], coef[o, 0, 1, m], coef[o, 1, 0, m], coef[o, 1, 1, m]
                a00 += c00 * l0
                d00 += c00 * l1
                a01 += c01 * l0
                d01 += c01 * l1
                a10 += c10 * l0
                d10 += c10 * l1
                a11 += c11 * l0
                d11 += c11 * l1
            e00 = e01 = e10 = e11 = np.nan
        out[o, 0] = lr0 * (ll0 * a00 + ll1 * a01) + lr1 * (ll0 * a10 + ll1 * a11)
        out[o, 1] = lr0 * (ll0 * d00 + ll1 * d01) + lr1 * (ll0 * d10 + ll1 * d11)
        out[o, 2] = lr0 * (ll0 * e00 + ll1 * e01) + lr1 * (ll0 * e10 + ll1 * e11)
        out[o, 3] = lr0 * (a00 - a01) + lr1 * (a10 - a11)
        out[o, 4] = (ll0 * a00 + ll1 * a01) - (ll0 * a10 + ll1 * a11)
        out[o, 5] = lr0 * (d00 - d01) + lr1 * (d10 - d11)
        out[o, 6] = (ll0 * d00 + ll1 * d01) - (ll0 * d10 + ll1 * d11)


@njit(cache=True)
def model_value(coef: Array, o: int, p: float, l: float, r: float) -> float:
    """``h`` of output ``o`` alone: ``model_terms(coef, p, l, r, out)`` then ``out[o, 0]``, by the same
    sums in the same order, at a third of the cost (the torque needs no derivative)."""
    K = coef.shape[3]
    w1 = 2.0 * np.pi
    c1, s1 = np.cos(w1 * p), np.sin(w1 * p)
    c, s = 1.0, 0.0
    a00, a01, a10, a11 = coef[o, 0, 0, 0], coef[o, 0, 1, 0], coef[o, 1, 0, 0], coef[o, 1, 1, 0]
    a00 = 0.0 + a00 * 1.0
    a01 = 0.0 + a01 * 1.0
    a10 = 0.0 + a10 * 1.0
    a11 = 0.0 + a11 * 1.0
    for k in range(1, (K - 1) // 2 + 1):
        c, s = c * c1 - s * s1, s * c1 + c * s1
        for m, b in ((2 * k - 1, c), (2 * k, s)):
            a00 += coef[o, 0, 0, m] * b
            a01 += coef[o, 0, 1, m] * b
            a10 += coef[o, 1, 0, m] * b
            a11 += coef[o, 1, 1, m] * b
    ll0, ll1 = l, 1.0 - l
    return r * (ll0 * a00 + ll1 * a01) + (1.0 - r) * (ll0 * a10 + ll1 * a11)


@njit(cache=True)
def bounded_torque(
    coef4: Array, p: float, l: float, r: float, cutoff: float, scale: float, mass_gain: float, max_torque: float
) -> float:
    """``TorqueProfile.torque_at(p, l, r, mass_gain, max_torque)`` scaled by ``scale``, as the compiled loops
    command it (``_batch``, ``_lock_batch``): 0 after ``cutoff`` or when not finite, else within [0, max]."""
    if not p % 1.0 <= cutoff:
        return 0.0
    tau = scale * mass_gain * model_value(coef4, 0, p, l, r)
    if not np.isfinite(tau):
        return 0.0
    if 0.0 > tau:  # max(tau, 0.0), then min(., max_torque), as Python picks between equals
        tau = 0.0
    if max_torque < tau:
        tau = max_torque
    return tau


@njit(cache=True)
def measurement(
    coef: Array, x: Array, leg_length: float, terms: Array, h: Array, H: Array, phase_column: bool = True
) -> None:
    """Predicted measurement ``h(x)`` (6,) and Jacobian ``H`` (6, 4) of seed 000 eq. 16-17.

    Channels: foot angle, foot velocity, shank angle, shank velocity (deg, deg/s), heel forward and
    heel up (m; the model is in leg lengths). State ``x = [p, pdot, lp, r]``. Without
    ``phase_column`` the velocity rows of ``H[:, 0]`` are NaN, which saves the second phase derivative
    (the heel-strike backup does not estimate the phase); every other entry is the same.
    """
    p, pdot, lp, r = x[0], x[1], x[2], x[3]
    l, dl = stride_from_pseudo(lp)
    model_terms(coef, p, l, r, terms, 2 if phase_column else 0)  # h_pp: foot and shank velocity rows only
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
def wrap(p: float) -> float:
    """``p`` modulo 1 in [0, 1): ``p - floor(p)``, except that a tiny negative ``p`` (which that rounds
    to 1.0) gives 0.0, the same point of the cycle."""
    w = p - np.floor(p)
    return 0.0 if w >= 1.0 else w


@njit(cache=True)
def predict(x: Array, P: Array, dt: float, q_diag: Array) -> None:
    """Constant-phase-rate prediction in place: ``x = F x``, ``P = F P F^T + Q`` (seed 000 eq. 13-14)."""
    x[0] = x[0] + dt * x[1]
    x[0] = wrap(x[0])
    # F = I + dt e0 e1^T: F P adds dt row 1 to row 0, (F P) F^T adds dt column 1 to column 0
    for j in range(4):
        P[0, j] += dt * P[1, j]
    for i in range(4):
        P[i, 0] += dt * P[i, 1]
    for i in range(4):
        P[i, i] += q_diag[i]


def _update_for(n_state: int) -> Any:
    """:func:`update` for states of ``n_state`` entries (0: any): loops of a known length compile to
    straight code. The same operations in the same order whatever the size, so the same numbers."""

    @njit(cache=True, error_model="numpy")
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
        """See :func:`update`."""
        n = x.shape[0] if n_state == 0 else n_state
        M = 6
        used = np.empty(M, dtype=np.bool_)
        m = 0
        for a in range(M):
            used[a] = np.isfinite(z[a])
            m += used[a]
        if m == 0:
            y_out[:] = np.nan
            S_out[:] = np.nan
            K_out[:] = np.nan
            return 0, 0.0, 0.0
        y = np.empty(M)
        Hs = np.empty((M, n))
        Rs = np.empty((M, M))
        for a in range(M):
            y[a] = z[a] - h[a] if used[a] else 0.0
            for j in range(n):
                Hs[a, j] = H[a, j] if used[a] else 0.0
            for b in range(M):
                Rs[a, b] = R[a, b] if used[a] and used[b] else (1.0 if a == b else 0.0)
        PHt = np.empty((n, M))  # P H^T
        for a in range(M):
            for i in range(n):
                acc = 0.0
                for j in range(n):
                    acc += P[i, j] * Hs[a, j]
                PHt[i, a] = acc
        S = np.empty((M, M))
        for a in range(M):
            for b in range(a, M):
                acc = Rs[a, b]
                for j in range(n):
                    acc += Hs[a, j] * PHt[j, b]
                S[a, b] = acc
                S[b, a] = acc
        L = np.zeros((M, M))  # S = L L^T
        logdet = 0.0
        for a in range(M):
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
        K = np.empty((n, M))
        w = np.empty(M)
        for i in range(n):
            for a in range(M):
                acc = PHt[i, a]
                for k in range(a):
                    acc -= L[a, k] * w[k]
                w[a] = acc / L[a, a]
            for a in range(M - 1, -1, -1):
                acc = w[a]
                for k in range(a + 1, M):
                    acc -= L[k, a] * K[i, k]
                K[i, a] = acc / L[a, a]
        maha2 = 0.0
        for a in range(M):
            acc = y[a]
            for k in range(a):
                acc -= L[a, k] * w[k]
            w[a] = acc / L[a, a]
            maha2 += w[a] * w[a]
        for i in range(n):
            acc = 0.0
            for a in range(M):
                acc += K[i, a] * y[a]
            x[i] += acc
        if wrap_phase:
            x[0] = wrap(x[0])
        # Joseph form: (I - K H) P (I - K H)^T + K R K^T
        IKH = np.eye(n)
        for i in range(n):
            for j in range(n):
                acc = 0.0
                for a in range(M):
                    acc += K[i, a] * Hs[a, j]
                IKH[i, j] -= acc
        T = np.empty((n, n))  # (I - K H) P in loops: a BLAS call costs more than this 4 x 4 product
        for i in range(n):
            for j in range(n):
                acc = 0.0
                for k in range(n):
                    acc += IKH[i, k] * P[k, j]
                T[i, j] = acc
        KR = np.empty((n, M))
        for i in range(n):
            for b in range(M):
                acc = 0.0
                for a in range(M):
                    acc += K[i, a] * Rs[a, b]
                KR[i, b] = acc
        for i in range(n):
            for j in range(i, n):
                acc = 0.0
                for k in range(n):
                    acc += T[i, k] * IKH[j, k]
                for b in range(M):
                    acc += KR[i, b] * K[j, b]
                P[i, j] = acc
                P[j, i] = acc
        for a in range(M):
            y_out[a] = y[a] if used[a] else np.nan
            for b in range(M):
                S_out[a, b] = S[a, b] if used[a] and used[b] else np.nan
            for i in range(n):
                K_out[i, a] = K[i, a] if used[a] else np.nan
        return m, maha2, logdet

    return update


_update_any = _update_for(0)
_update_4 = _update_for(4)
_update_2 = _update_for(2)


@njit(cache=True, error_model="numpy")
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

    A missing channel is not cut out but neutralised: zero innovation and Jacobian row, unit variance
    and no correlation. Its gain is then exactly 0 and every sum over channels gains only exact zeros,
    so the result equals the update on the used channels alone, while every loop runs over six
    channels; the phase EKF's four states and the backup's two are compiled apart too. Loops of fixed
    length compile to straight code, without the branch mispredictions of loops whose length changes
    from sample to sample (a third of the time). A zero or negative pivot gives inf or NaN (numpy's
    error model, not an exception): the caller's health check sees a diverged filter.

    Returns:
        ``(m, y^T S^-1 y, log det S)`` with m the number of channels used.
    """
    n = x.shape[0]
    if n == 4:
        return _update_4(x, P, z, h, H, R, y_out, S_out, K_out, wrap_phase)
    if n == 2:
        return _update_2(x, P, z, h, H, R, y_out, S_out, K_out, wrap_phase)
    return _update_any(x, P, z, h, H, R, y_out, S_out, K_out, wrap_phase)


@njit(cache=True, error_model="numpy")
def cholesky_used(R: Array, used: NDArray[np.bool_], L: Array) -> None:
    """``L`` (6, 6, lower triangle) with ``L L^T`` = R on the ``used`` channels, a missing channel
    neutralised as in :func:`update` (unit variance, no correlation)."""
    M = 6
    for a in range(M):
        for b in range(a + 1):
            acc = R[a, b] if used[a] and used[b] else (1.0 if a == b else 0.0)
            for k in range(b):
                acc -= L[a, k] * L[b, k]
            L[a, b] = np.sqrt(acc) if a == b else acc / L[b, b]


@njit(cache=True, error_model="numpy")
def whitened_sse(L: Array, y: Array, used: NDArray[np.bool_]) -> float:
    """``|L^-1 y|^2`` over the ``used`` entries of ``y`` (the others count as 0)."""
    M = 6
    w = np.empty(M)
    sse = 0.0
    for a in range(M):
        acc = y[a] if used[a] else 0.0
        for k in range(a):
            acc -= L[a, k] * w[k]
        w[a] = acc / L[a, a]
        sse += w[a] * w[a]
    return sse


@njit(cache=True, error_model="numpy")
def weighted_sse(y: Array, R: Array) -> float:
    """``y^T R_s^-1 y`` over the finite entries of ``y`` (6,), R_s the matching sub-matrix of R (positive
    definite): ``|L^-1 y|^2`` with ``R_s = L L^T`` (Cholesky in loops, a missing channel neutralised as
    in :func:`update`; a LAPACK solve costs several times more for six channels)."""
    used = np.isfinite(y)
    L = np.zeros((6, 6))
    cholesky_used(R, used, L)
    return whitened_sse(L, y, used)


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


@njit(cache=True)
def highpass_step(b: Array, a: Array, zi_unit: Array, zi: Array, started: bool, x: Array) -> bool:
    """One sample of :class:`~gaitscope.estimators.highpass.HighPassFilter` (direct form II transposed) on ``x``
    ``(c,)`` in place, state ``zi`` ``(2, c)``; returns whether the filter is started.

    A sample with a non-finite value is left as it is and does not move the filter. A filter not yet
    started begins in the steady state of this sample; one whose output is not finite (cannot happen
    with bounded input) restarts that way, so it never sticks on NaN.
    """
    n = x.shape[0]
    for j in range(n):
        if not np.isfinite(x[j]):
            return started
    xs = x.copy()
    for _ in range(2):
        if not started:
            for i in range(2):
                for j in range(n):
                    zi[i, j] = zi_unit[i] * xs[j]
            started = True
        ok = True
        for j in range(n):
            o = b[0] * xs[j] + zi[0, j]
            zi[0, j] = b[1] * xs[j] - a[1] * o + zi[1, j]
            zi[1, j] = b[2] * xs[j] - a[2] * o
            x[j] = o
            ok = ok and np.isfinite(o)
        if ok:
            break
        started = False
    return started


# --- the phase EKF's state in one buffer ------------------------------------------------------------------
# :class:`~gaitscope.estimators.phase_ekf.PhaseEKF` keeps x, P, y, S, K, z_pred, H, R, its scratch and its
# constants in one float array, its attributes being views of it, so that a step passes one array to the
# compiled code instead of thirteen (each array argument costs numba's dispatcher about 50 ns to unbox).
# Offsets into that buffer:
EKF_X, EKF_P, EKF_Y, EKF_S, EKF_K, EKF_ZPRED, EKF_H, EKF_R, EKF_TERMS = 0, 4, 20, 26, 62, 86, 92, 116, 152
#: scalars: leg length, the last update's Mahalanobis distance and log-likelihood, log(2 pi)
EKF_LEG, EKF_MAHA, EKF_LL, EKF_LOG2PI = 180, 181, 182, 183
#: process noise: ``q_std`` squared (3), ``q_time_unit``, ``process_noise_scale``, ``no_task`` (1.0 / 0.0)
EKF_QVAR, EKF_QUNIT, EKF_QSCALE, EKF_NOTASK = 184, 187, 188, 189
EKF_SIZE = 190
_FROZEN_VARIANCE = 1e-20  # gaitscope.estimators.phase_ekf.FROZEN_VARIANCE


@njit(cache=True)
def ekf_predict(buf: Array, dt: float) -> None:
    """:func:`predict` of the state in ``buf`` over ``dt``, with ``Q`` as ``EKFConfig.q_diag`` makes it (the
    same operations in the same order)."""
    x = buf[EKF_X : EKF_X + 4]
    P = buf[EKF_P : EKF_P + 16].reshape((4, 4))
    c = dt / buf[EKF_QUNIT]
    scale = buf[EKF_QSCALE]
    q = np.empty(4)
    q[0] = 0.0
    q[1] = buf[EKF_QVAR] * c * scale
    q[2] = buf[EKF_QVAR + 1] * c * scale
    q[3] = buf[EKF_QVAR + 2] * c * scale
    if buf[EKF_NOTASK] != 0.0:
        q[2] = q[3] = _FROZEN_VARIANCE
    predict(x, P, dt, q)


@njit(cache=True)
def ekf_update_buffer(coef: Array, bins: Array, buf: Array, z: Array) -> None:
    """:func:`ekf_update` on the state in ``buf``, then the Mahalanobis distance ``sqrt(y^T S^-1 y)`` and the
    log-likelihood ``-(y^T S^-1 y + log det S + m log 2 pi) / 2`` (0 with no channel) into ``buf``."""
    m, maha2, logdet = ekf_update(
        coef,
        buf[EKF_X : EKF_X + 4],
        buf[EKF_P : EKF_P + 16].reshape((4, 4)),
        z,
        buf[EKF_LEG],
        bins,
        buf[EKF_TERMS : EKF_TERMS + 28].reshape((4, 7)),
        buf[EKF_ZPRED : EKF_ZPRED + 6],
        buf[EKF_H : EKF_H + 24].reshape((6, 4)),
        buf[EKF_R : EKF_R + 36].reshape((6, 6)),
        buf[EKF_Y : EKF_Y + 6],
        buf[EKF_S : EKF_S + 36].reshape((6, 6)),
        buf[EKF_K : EKF_K + 24].reshape((4, 6)),
    )
    buf[EKF_MAHA] = np.sqrt(maha2)
    buf[EKF_LL] = -0.5 * (maha2 + logdet + m * buf[EKF_LOG2PI]) if m else 0.0


@njit(cache=True, error_model="numpy")
def backup_update(
    coef: Array,
    leg_length: float,
    phase: float,
    phase_rate: float,
    x: Array,
    P: Array,
    z: Array,
    bins: Array,
    R: Array,
    own_noise: bool,
    rbar: Array,
    ekf_y: Array,
    work: Array,
    y: Array,
    S: Array,
    K: Array,
) -> tuple[float, float]:
    """The heel-strike backup's measurement update in one compiled call (``HeelStrikeBackup.track``).

    ``h`` and the ``[lp, r]`` columns of ``H`` at ``[phase, phase_rate, x]`` (:func:`measurement`), ``R`` made
    from ``bins`` at ``phase`` first when ``own_noise`` (standalone; coupled it is the EKF's), then
    :func:`update` of ``x``, ``P`` on ``z``. ``work``: ``(4 + 28 + 6 + 24 + 12,)`` scratch.

    Returns:
        ``(y^T Rbar^-1 y, ekf_y^T Rbar^-1 ekf_y)``: the backup's and the EKF's weighted innovations
        (:func:`weighted_sse`; the second is 0 when ``ekf_y`` is empty, standalone).
    """
    x4 = work[0:4]
    terms = work[4:32].reshape((4, 7))
    h = work[32:38]
    H = work[38:62].reshape((6, 4))
    H2 = work[62:74].reshape((6, 2))
    x4[0], x4[1], x4[2], x4[3] = phase, phase_rate, x[0], x[1]
    measurement(coef, x4, leg_length, terms, h, H, False)  # the [lp, r] columns need no second derivative
    for i in range(6):
        H2[i, 0], H2[i, 1] = H[i, 2], H[i, 3]
    if own_noise:
        noise_at(bins, phase, R)
    update(x, P, z, h, H2, R, y, S, K, False)
    sse_hp = weighted_sse(y, rbar)
    sse_ekf = weighted_sse(ekf_y, rbar) if ekf_y.shape[0] == 6 else 0.0
    return sse_hp, sse_ekf


@njit(cache=True)
def finite_sum(y: Array) -> bool:
    """Whether the left-to-right sum of ``y`` is finite (Python's ``math.isfinite(sum(y.tolist()))``: every
    entry finite and no overflow), for the estimator stack's health check."""
    acc = 0.0
    for i in range(y.shape[0]):
        acc += y[i]
    return np.isfinite(acc)


@njit(cache=True)
def covariance_ok(P: Array, max_variance: float) -> bool:
    """Whether the row-major sum of ``P`` is finite (as :func:`finite_sum`) and its diagonal in
    ``[0, max_variance]``, for the estimator stack's health check."""
    acc = 0.0
    for i in range(P.shape[0]):
        for j in range(P.shape[1]):
            acc += P[i, j]
    if not np.isfinite(acc):
        return False
    for i in range(min(P.shape[0], P.shape[1])):
        if P[i, i] < 0.0 or P[i, i] > max_variance:
            return False
    return True


@njit(cache=True)
def outputs_ok(y: Array, P: Array, max_variance: float) -> bool:
    """:func:`finite_sum` of ``y`` and :func:`covariance_ok` of ``P`` in one call."""
    return finite_sum(y) and covariance_ok(P, max_variance)

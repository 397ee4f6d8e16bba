"""Compiled step of the gait-fingerprint EKF (numba). Private: use :class:`estimators.fingerprint.FingerprintEKF`.

The same maths as :meth:`FingerprintEKF.measurement` and :meth:`FingerprintEKF.update` (numpy, the test
oracle), as scalar loops: the two measurements are taken one after the other, which with a diagonal ``R``
and one linearisation point is the joint update exactly.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from gaitscope.estimators.basis import Array


@njit(cache=True)
def _terms(p: float, l: float, xi: Array, order: int, f: Array, d: Array) -> tuple[float, float, float, float, float]:
    """Fill the Fourier basis ``f`` and its phase derivative ``d`` at ``p``; return ``h, h_p, h_pp, h_l, h_pl``
    of the model ``xi`` (columns ``[f0, f0 l, f1, f1 l, ...]``)."""
    w1 = 2.0 * np.pi
    s1, c1 = np.sin(w1 * p), np.cos(w1 * p)
    s, c = 0.0, 1.0
    f[0], d[0] = 1.0, 0.0
    h = xi[0] + l * xi[1]
    hl = xi[1]
    hp = hpp = hpl = 0.0
    for k in range(1, order):
        s, c = s * c1 + c * s1, c * c1 - s * s1  # sin, cos of 2 pi k p by angle addition
        w = w1 * k
        m = 2 * k - 1
        f[m], f[m + 1] = s, c
        d[m], d[m + 1] = w * c, -w * s
        a_s = xi[2 * m] + l * xi[2 * m + 1]
        a_c = xi[2 * m + 2] + l * xi[2 * m + 3]
        h += s * a_s + c * a_c
        hp += w * (c * a_s - s * a_c)
        hpp += -w * w * (s * a_s + c * a_c)
        hl += s * xi[2 * m + 1] + c * xi[2 * m + 3]
        hpl += w * (c * xi[2 * m + 1] - s * xi[2 * m + 3])
    return h, hp, hpp, hl, hpl


@njit(cache=True)
def _model(x: Array, xi_avg: Array, p_map: Array, xi_fixed: Array, gf: bool, xi: Array) -> None:
    """``xi = xi_avg + g P_map`` (``g = x[3:]``) for GF, else the fixed model."""
    if not gf:
        xi[:] = xi_fixed
        return
    xi[:] = xi_avg
    for i in range(p_map.shape[0]):
        gi = x[3 + i]
        for j in range(xi.size):
            xi[j] += gi * p_map[i, j]


@njit(cache=True)
def fp_step(
    x: Array,
    P: Array,
    xi_avg: Array,
    p_map: Array,
    xi_fixed: Array,
    gf: bool,
    q: Array,
    r: float,
    edge: float,
    edge_a: float,
    edge_v: float,
    pdot_min: float,
    l_lo: float,
    l_hi: float,
    dt: float,
    za: float,
    zv: float,
    order: int,
    work: Array,
) -> float:
    """Predict over ``dt``, update on thigh angle ``za`` and velocity ``zv`` (NaN: skipped), wrap and clip;
    ``x`` and ``P`` in place. Returns the model's thigh angle at the new state. ``work``: ``(4 + 2 c + 3 n,)``
    scratch, ``c`` parameters, ``n`` states."""
    n = x.size
    c = xi_avg.size
    nb = c // 2
    xi = work[:c]
    f = work[c : c + nb]
    d = work[c + nb : c + 2 * nb]
    hrow = work[c + 2 * nb : c + 2 * nb + n]
    pht = work[c + 2 * nb + n : c + 2 * nb + 2 * n]
    x0 = work[c + 2 * nb + 2 * n : c + 2 * nb + 3 * n]
    # predict: x0 <- p + dt pdot; P <- F P F^T + Q
    x[0] = (x[0] + dt * x[1]) % 1.0
    for j in range(n):
        P[0, j] += dt * P[1, j]
    for i in range(n):
        P[i, 0] += dt * P[i, 1]
    for i in range(n):
        P[i, i] += q[i]
    _model(x, xi_avg, p_map, xi_fixed, gf, xi)
    p, pdot, l = x[0], x[1], x[2]
    h, hp, hpp, hl, hpl = _terms(p, l, xi, order, f, d)
    ra = rv = r
    if p < edge or p > 1.0 - edge:
        ra, rv = r * edge_a, r * edge_v
    for i in range(n):
        x0[i] = x[i]
    for row in range(2):
        z = za if row == 0 else zv
        if not np.isfinite(z):
            continue
        for i in range(n):
            hrow[i] = 0.0
        if row == 0:
            hrow[0], hrow[2] = hp, hl
            pred, rr = h, ra
        else:
            hrow[0], hrow[1], hrow[2] = pdot * hpp, hp, pdot * hpl
            pred, rr = pdot * hp, rv
        if gf:
            for i in range(p_map.shape[0]):
                acc = 0.0
                for m in range(nb):
                    base = p_map[i, 2 * m] + l * p_map[i, 2 * m + 1]
                    acc += (f[m] if row == 0 else pdot * d[m]) * base
                hrow[3 + i] = acc
        # innovation at the prior's linearisation: z - h(x0) - H (x - x0)
        y = z - pred
        for i in range(n):
            y -= hrow[i] * (x[i] - x0[i])
        s = rr
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += P[i, j] * hrow[j]
            pht[i] = acc
            s += hrow[i] * acc
        for i in range(n):
            x[i] += pht[i] / s * y
        for i in range(n):
            ki = pht[i] / s
            for j in range(n):
                P[i, j] -= ki * pht[j]
    for i in range(n):
        for j in range(i + 1, n):
            m2 = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = m2
            P[j, i] = m2
    x[0] = x[0] % 1.0
    if x[1] < pdot_min:
        x[1] = pdot_min
    x[2] = min(max(x[2], l_lo), l_hi)
    _model(x, xi_avg, p_map, xi_fixed, gf, xi)
    return _terms(x[0], x[2], xi, order, f, d)[0]


#: The layout of :func:`fp_stream_step`'s ``prm``: GF (1.0 / 0.0), R's base variance, the edge phase and the
#: angle's and velocity's scales there, the phase rate's floor, the stride length's range, the Fourier order.
PRM_GF, PRM_R, PRM_EDGE, PRM_EDGE_A, PRM_EDGE_V, PRM_PDOT_MIN, PRM_L_LO, PRM_L_HI, PRM_ORDER = range(9)
PRM_SIZE = 9


@njit(cache=True)
def fp_stream_step(
    x: Array,
    P: Array,
    xi_avg: Array,
    p_map: Array,
    xi_fixed: Array,
    q: Array,
    prm: Array,
    dt: float,
    za: float,
    zv: float,
    work: Array,
) -> Array:
    """:func:`fp_step` with its constants in ``prm`` (``PRM_*``: one array for the dispatcher to unbox, not
    twelve numbers), returning the stack estimator's outputs: ``[p, pdot, l, thigh model, g...]`` (``g`` in GF
    mode only)."""
    gf = prm[PRM_GF] != 0.0
    pred = fp_step(
        x,
        P,
        xi_avg,
        p_map,
        xi_fixed,
        gf,
        q,
        prm[PRM_R],
        prm[PRM_EDGE],
        prm[PRM_EDGE_A],
        prm[PRM_EDGE_V],
        prm[PRM_PDOT_MIN],
        prm[PRM_L_LO],
        prm[PRM_L_HI],
        dt,
        za,
        zv,
        int(prm[PRM_ORDER]),
        work,
    )
    n_g = x.size - 3 if gf else 0
    out = np.empty(4 + n_g)
    out[0], out[1], out[2], out[3] = x[0], x[1], x[2], pred
    for i in range(n_g):
        out[4 + i] = x[3 + i]
    return out

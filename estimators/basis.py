"""Kronecker regressor of the gait model (seed 000 section II-A, eq. 5-8).

``R(p, l, r) = Lambda_r(r) (x) Lambda_l(l) (x) Lambda_p(p)`` with

- ``Lambda_r = [r, 1 - r]``, r the incline in degrees;
- ``Lambda_l = [l, 1 - l]``, l the stride length normalised by leg length;
- ``Lambda_p = [1, cos 2 pi p, sin 2 pi p, ..., cos 2 pi N p, sin 2 pi N p]``, ``2 N + 1`` terms.

With N = 20 that is 2 x 2 x 41 = 164 columns (the paper's text says 160; the digest in
``shared/reference/estimators.md`` counts 164, which is what the formula gives).

Coefficients of one output are stored as an array of shape ``(2, 2, 2N+1)`` indexed ``[i_r, i_l, m]``;
flattened in C order it matches the column order of :func:`regressor`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]

#: Derivative of Lambda_r with respect to r and of Lambda_l with respect to l.
D_LINEAR = np.array([1.0, -1.0])


def n_terms(order: int) -> int:
    """Number of Fourier terms for order N: ``2 N + 1``."""
    return 2 * order + 1


def fourier(p: Array, order: int, derivative: int = 0) -> Array:
    """Fourier basis Lambda_p and its phase derivatives, vectorised.

    Args:
        p: phases, shape ``(n,)``, any real (the basis is 1-periodic).
        order: N, the highest harmonic.
        derivative: 0, 1 or 2 for Lambda_p, dLambda_p/dp, d2Lambda_p/dp2.

    Returns:
        Array of shape ``(n, 2N + 1)``, columns ``[1, cos 2 pi p, sin 2 pi p, cos 4 pi p, ...]``.
    """
    p = np.asarray(p, dtype=np.float64).reshape(-1)
    w = 2.0 * np.pi * np.arange(1, order + 1)
    arg = np.outer(p, w)
    c, s = np.cos(arg), np.sin(arg)
    out = np.empty((p.size, n_terms(order)))
    if derivative == 0:
        out[:, 0] = 1.0
        out[:, 1::2], out[:, 2::2] = c, s
    elif derivative == 1:
        out[:, 0] = 0.0
        out[:, 1::2], out[:, 2::2] = -w * s, w * c
    elif derivative == 2:
        out[:, 0] = 0.0
        out[:, 1::2], out[:, 2::2] = -(w**2) * c, -(w**2) * s
    else:
        raise ValueError(f"derivative must be 0, 1 or 2, not {derivative}")
    return out


def linear(v: Array, derivative: int = 0) -> Array:
    """``[v, 1 - v]`` (Lambda_r, Lambda_l) or its derivative ``[1, -1]``; shape ``(n, 2)``."""
    v = np.asarray(v, dtype=np.float64).reshape(-1)
    if derivative == 0:
        return np.stack([v, 1.0 - v], axis=1)
    if derivative == 1:
        return np.broadcast_to(D_LINEAR, (v.size, 2)).copy()
    return np.zeros((v.size, 2))


def regressor(p: Array, l: Array, r: Array, order: int, *, dp: int = 0, dl: int = 0, dr: int = 0) -> Array:
    """Rows ``R(p, l, r)`` of the Kronecker regressor or of its partial derivatives.

    Args:
        p, l, r: phase, normalised stride length and incline (deg), each shape ``(n,)``.
        order: Fourier order N.
        dp, dl, dr: derivative orders in p (0-2), l (0-1) and r (0-1).

    Returns:
        Array of shape ``(n, 4 (2N + 1))``; ``regressor(...) @ coef.reshape(-1)`` is the model output.
    """
    lp = fourier(p, order, dp)
    ll = linear(l, dl)
    lr = linear(r, dr)
    n = lp.shape[0]
    return np.einsum("ni,nj,nm->nijm", lr, ll, lp).reshape(n, -1)

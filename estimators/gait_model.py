"""Gait model fitted by equality-constrained least squares, and its heteroscedastic noise model.

Seed 000 section II-A/II-B. Four outputs share one Kronecker regressor (:mod:`gaitscope.estimators.basis`):

====  ======================  ==========================================
idx   output                  unit
====  ======================  ==========================================
0     global foot angle       deg (from horizontal, + toes up)
1     global shank angle      deg (from vertical, + ankle ahead of knee)
2     heel forward position   leg lengths, after the high-pass filter
3     heel up position        leg lengths, after the high-pass filter
====  ======================  ==========================================

Choice (the paper is silent): heel positions are modelled in leg lengths and multiplied by the user's
leg length at run time, so one model serves users of any size; ``heel_in_leg_lengths=False`` in
:func:`gaitscope.estimators.phase_ekf.PhaseEKF` is not offered because a model fitted this way cannot be used
otherwise. Stride length ``l`` enters the regressor normalised by leg length, as in the paper.

Constraints (seed 000 eq. 9-11, as used in the authors' code):

1. at ``l = 0``, for 100 phases and ``r in {0, 10, -10}``: every output is 0 except the foot angle,
   which equals ``r`` (standing still on a slope the foot lies on it);
2. foot only: ``d foot / d l = 0`` at ``p = 0.2``, ``l = 2``, ``r in {10, 0, -10}``; with (1) the foot
   angle at ``p = 0.2`` equals ``r`` for every stride length (eq. 11).

The constraint rows are linearly dependent (300 rows on an 82-dimensional face of the model), so a KKT
matrix would be singular; :func:`solve_constrained` works in the constraints' null space instead.

Fitting is split into per-subject Gram matrices (:class:`Gram`) so that leave-one-subject-out
cross-validation refits a model by summing nine Grams rather than touching the data again.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg

from gaitscope.estimators.basis import Array, n_terms, regressor

N_OUTPUTS = 4
#: Indices of the gait model's outputs (the rows of its coefficients; the columns of :func:`evaluate`).
OUT_FOOT, OUT_SHANK, OUT_HEEL_FORWARD, OUT_HEEL_UP = range(N_OUTPUTS)
#: Measurement channels of the EKF, in order (seed 000 eq. 16).
CHANNELS = ("foot_angle", "foot_vel", "shank_angle", "shank_vel", "heel_forward", "heel_up")
N_CHANNELS = len(CHANNELS)
#: Indices of the measurement channels in a measurement vector ``z`` (the order of :data:`CHANNELS`).
Z_FOOT_ANGLE, Z_FOOT_VEL, Z_SHANK_ANGLE, Z_SHANK_VEL, Z_HEEL_FORWARD, Z_HEEL_UP = range(N_CHANNELS)
#: Sensor covariance of seed 000 (deg, deg/s, m): diag(1^2, 10^2, 7^2, 20^2, 0.01^2, 0.08^2).
SENSOR_VARIANCE = np.array([1.0**2, 10.0**2, 7.0**2, 20.0**2, 0.01**2, 0.08**2])

CONSTRAINT_PHASES = 100
CONSTRAINT_INCLINES = (0.0, 10.0, -10.0)


@dataclass
class Gram:
    """Sufficient statistics of a least-squares fit: ``G = A^T A``, ``b = A^T Y``, ``n`` rows.

    Attributes:
        G: ``(k, k)`` with k = 4 (2N + 1).
        b: ``(k, n_outputs)``.
        n: number of samples summed.
    """

    G: Array
    b: Array
    n: int

    def __add__(self, other: Gram) -> Gram:
        return Gram(self.G + other.G, self.b + other.b, self.n + other.n)


def gram(p: Array, l: Array, r: Array, y: Array, order: int, chunk: int = 50_000) -> Gram:
    """Accumulate ``A^T A`` and ``A^T y`` for samples ``(p, l, r) -> y`` (``y`` shape ``(n, n_outputs)``)."""
    y = np.asarray(y, dtype=np.float64).reshape(len(p), -1)
    k = 4 * n_terms(order)
    G = np.zeros((k, k))
    b = np.zeros((k, y.shape[1]))
    for s in range(0, len(p), chunk):
        A = regressor(p[s : s + chunk], l[s : s + chunk], r[s : s + chunk], order)
        G += A.T @ A
        b += A.T @ y[s : s + chunk]
    return Gram(G, b, len(p))


def solve_constrained(G: Array, b: Array, C: Array | None, d: Array | None, ridge: float = 0.0) -> Array:
    """Minimise ``||A x - y||^2`` subject to ``C x = d`` given ``G = A^T A`` and ``b = A^T y``.

    Null-space method: ``x = x_p + N z`` with ``x_p`` the minimum-norm solution of ``C x = d`` and ``N``
    an orthonormal basis of ``null(C)`` (from the SVD, so dependent constraint rows are harmless).

    Args:
        G: ``(k, k)`` Gram matrix.
        b: ``(k,)`` right-hand side.
        C, d: constraints ``(m, k)`` and ``(m,)``, or None for an unconstrained fit.
        ridge: Tikhonov weight added to the reduced normal equations (0 in the paper).

    Returns:
        The coefficients, shape ``(k,)``.
    """
    k = G.shape[0]
    if C is None or d is None:
        x_p, N = np.zeros(k), np.eye(k)
    else:
        U, s, Vt = linalg.svd(C, full_matrices=True)
        rank = int(np.sum(s > s[0] * 1e-12))
        x_p = Vt[:rank].T @ ((U[:, :rank].T @ d) / s[:rank])
        N = Vt[rank:].T
    Gn = N.T @ G @ N + ridge * np.eye(N.shape[1])
    z = linalg.solve(Gn, N.T @ (b - G @ x_p), assume_a="sym")
    return x_p + N @ z


def gait_constraints(order: int, output: int) -> tuple[Array, Array]:
    """Constraint rows ``C coef = d`` of one output (seed 000 eq. 9-11)."""
    ph = np.arange(CONSTRAINT_PHASES) / CONSTRAINT_PHASES
    rr = np.repeat(np.asarray(CONSTRAINT_INCLINES), CONSTRAINT_PHASES)
    pp = np.tile(ph, len(CONSTRAINT_INCLINES))
    C = regressor(pp, np.zeros_like(pp), rr, order)
    d = rr.copy() if output == OUT_FOOT else np.zeros_like(rr)
    if output == OUT_FOOT:
        r2 = np.asarray(CONSTRAINT_INCLINES)
        C2 = regressor(np.full(3, 0.2), np.full(3, 2.0), r2, order, dl=1)
        C = np.vstack([C, C2])
        d = np.concatenate([d, np.zeros(3)])
    return C, d


def fit_outputs(g: Gram, order: int, constrained: bool = True, ridge: float = 0.0) -> Array:
    """Fit all outputs of the gait model from a summed Gram; returns coefficients ``(4, 2, 2, 2N+1)``."""
    K = n_terms(order)
    coef = np.empty((g.b.shape[1], 2, 2, K))
    for o in range(g.b.shape[1]):
        C, d = gait_constraints(order, o) if constrained else (None, None)
        coef[o] = solve_constrained(g.G, g.b[:, o], C, d, ridge).reshape(2, 2, K)
    return coef


def evaluate(coef: Array, p: Array, l: Array, r: Array, *, dp: int = 0, dl: int = 0, dr: int = 0) -> Array:
    """Model outputs (or partial derivatives) at arrays of states; returns ``(n, n_outputs)``."""
    order = (coef.shape[-1] - 1) // 2
    A = regressor(p, l, r, order, dp=dp, dl=dl, dr=dr)
    return A @ coef.reshape(coef.shape[0], -1).T


@dataclass(frozen=True)
class NoiseModel:
    """Heteroscedastic measurement covariance ``Sigma_R(p) = diag(sensor) + Sigma_xsub(p)`` (II-C4).

    Attributes:
        residual_cov: ``(B, 6, 6)`` uncentred residual covariance at phases ``b / B``.
        sensor_var: ``(6,)`` sensor variances (deg^2, (deg/s)^2, m^2).
    """

    residual_cov: Array
    sensor_var: Array

    @property
    def bins(self) -> Array:
        """``(B, 6, 6)`` total covariance at each phase bin."""
        return self.residual_cov + np.diag(self.sensor_var)[None]

    def at(self, p: float) -> Array:
        """``Sigma_R(p)``, each entry interpolated linearly in phase (periodic)."""
        B = self.residual_cov.shape[0]
        u = (p % 1.0) * B
        i0 = int(np.floor(u)) % B
        f = u - np.floor(u)
        return (1.0 - f) * self.bins[i0] + f * self.bins[(i0 + 1) % B]

    def mean(self) -> Array:
        """Time average of ``Sigma_R`` over phase (the backup filter's R, section II-D)."""
        return self.bins.mean(axis=0)


def residual_covariance(p: Array, residuals: Array, n_bins: int = 150) -> Array:
    """Per-phase-bin uncentred covariance ``X^T X / (N - 1)`` of residuals (seed 000 II-C4).

    Args:
        p: phases of the residual samples, ``(n,)``.
        residuals: ``(n, 6)``, ``z - h(x_true)``; NaN rows are ignored.
        n_bins: bins at phases ``b / n_bins``; a sample goes to the nearest bin (periodic).

    Returns:
        ``(n_bins, 6, 6)``.
    """
    ok = np.all(np.isfinite(residuals), axis=1)
    p, residuals = p[ok], residuals[ok]
    idx = np.rint((p % 1.0) * n_bins).astype(np.int64) % n_bins
    out = np.empty((n_bins, residuals.shape[1], residuals.shape[1]))
    outer = residuals[:, :, None] * residuals[:, None, :]
    sums = np.zeros_like(out)
    np.add.at(sums, idx, outer)
    counts = np.bincount(idx, minlength=n_bins)
    if np.any(counts < 2):
        raise ValueError(f"phase bins {np.flatnonzero(counts < 2).tolist()} have fewer than 2 residuals")
    out[:] = sums / (counts - 1)[:, None, None]
    return out

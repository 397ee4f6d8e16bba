"""Gait fingerprints: a low-dimensional map of how people's thigh-angle patterns differ (seed 004).

Montes Pérez, Thomas and Gregg fit one thigh-angle model per training subject, move the fits' differences
from their average into an "RMSE space" where a vector's length is the RMS change of the model's
prediction over the training data, and keep the principal components of that space as the *personalization
map*. A new person's model is then ``xi(g) = xi_avg + g P_map`` with a few numbers ``g`` (their gait
fingerprint), found by least squares from a calibration walk (LS-GF) or estimated live by an EKF whose
state carries them (GF). Everything here is pure numpy; the session code builds maps from the cohort
(:mod:`gaitscope.sessions.offline.fingerprints`) and runs the filters in a stack (:class:`FingerprintEKF` implements
:class:`gaitscope.estimators.protocol.Estimator`).

Choices where the paper is silent or inconsistent (each a parameter; ``docs/estimators.md`` lists them):

- Basis (seed 004 eq. 11, Sec. IV): Fourier in phase of order 4 (``[1, sin 2 pi p, cos 2 pi p, ...,
  sin 6 pi p, cos 6 pi p]``, 7 terms) (x) constant in phase rate (x) ``[1, l]`` with ``l`` the stride length
  in metres: 14 parameters. Phase enters as ``2 pi p`` (the paper writes ``F_k(x)`` without the period).
- ``P_map`` (eq. 35 writes ``U^T diag(psi) U``, which is not a map from ``g`` to parameters): the authors'
  code's form, ``P_map = U_k^T G^(-1/2)``, rows the first ``k`` principal directions of RMSE space taken
  back to parameter space, so that ``g_i = 1`` changes the prediction by 1 deg RMS over the training data.
- ``k``: the smallest number of components whose cumulative share of the variance exceeds
  ``variance_threshold`` (paper: 99 %, which gave 3), or ``n_components`` when given.
- ``G = sum_x Lambda(x)^T Lambda(x) / N`` over every training sample of every subject (eq. 19).
- Measurement noise (eq. 41 averages absolute, not squared, residuals): the authors' code's
  ``R = 0.9 diag(rbar^2, rbar^2)`` with ``rbar`` the mean over training subjects of each one's own-fit
  RMSE (deg), the same figure for the angle (deg^2) and its velocity ((deg/s)^2); near heel strike
  (phase < 0.05 or > 0.95) the angle variance x 2 and the velocity variance x 10 (Sec. IV-E).
- Process noise per step, not per second (the code's): GF ``[0, 9e-8, 6e-8, 5e-6, 4e-10, 4e-10]`` (the
  paper's text gives 4e-10 for ``g1`` too), AVG and LS-GF ``[0, 2e-8, 7e-8]``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Final, Literal

import numpy as np
from numpy.typing import NDArray

from gaitscope.estimators._fp_kernel import (
    PRM_EDGE,
    PRM_EDGE_A,
    PRM_EDGE_V,
    PRM_GF,
    PRM_L_HI,
    PRM_L_LO,
    PRM_ORDER,
    PRM_PDOT_MIN,
    PRM_R,
    PRM_SIZE,
    fp_stream_step,
)
from gaitscope.estimators.channels import positions
from gaitscope.estimators.descriptor import Descriptor, OutputSpec, Tunable, out
from gaitscope.estimators.protocol import MAX_GAP_S, Output, check_params, elapsed

__all__ = [
    "FOURIER_ORDER",
    "FingerprintConfig",
    "FingerprintEKF",
    "FingerprintMap",
    "Mode",
    "basis",
    "basis_dp",
    "descriptor",
    "fit_map",
    "fit_subject",
]

Array = NDArray[np.float64]
Mode = Literal["avg", "ls", "gf"]

#: Fourier order of the phase basis (seed 004 Sec. IV: fourth order, 7 terms).
FOURIER_ORDER: Final = 4
N_PARAMS: Final = 2 * (2 * FOURIER_ORDER - 1)


def _fourier(p: Array, order: int) -> tuple[Array, Array, Array]:
    """``F(p)``, ``dF/dp``, ``d2F/dp2`` of ``[1, sin 2 pi p, cos 2 pi p, ...]``: ``(n, 2 order - 1)`` each."""
    p = np.asarray(p, dtype=np.float64).reshape(-1)
    n = p.size
    f = np.empty((n, 2 * order - 1))
    d = np.empty_like(f)
    d2 = np.empty_like(f)
    f[:, 0], d[:, 0], d2[:, 0] = 1.0, 0.0, 0.0
    for k in range(1, order):
        w = 2.0 * math.pi * k
        s, c = np.sin(w * p), np.cos(w * p)
        f[:, 2 * k - 1], f[:, 2 * k] = s, c
        d[:, 2 * k - 1], d[:, 2 * k] = w * c, -w * s
        d2[:, 2 * k - 1], d2[:, 2 * k] = -w * w * s, -w * w * c
    return f, d, d2


def _kron_l(f: Array, l: Array) -> Array:
    """Row-wise ``f (x) [1, l]``: columns ``[f0, f0 l, f1, f1 l, ...]``."""
    l = np.asarray(l, dtype=np.float64).reshape(-1, 1)
    out = np.empty((f.shape[0], 2 * f.shape[1]))
    out[:, 0::2] = f
    out[:, 1::2] = f * l
    return out


def basis(p: Array, l: Array, order: int = FOURIER_ORDER) -> Array:
    """``Lambda(p, l)``, ``(n, 2 (2 order - 1))``: the model predicts ``basis @ xi`` (deg)."""
    return _kron_l(_fourier(p, order)[0], l)


def basis_dp(p: Array, l: Array, order: int = FOURIER_ORDER) -> Array:
    """``d Lambda / dp``: the model's angular velocity is ``pdot basis_dp @ xi`` (eq. 8)."""
    return _kron_l(_fourier(p, order)[1], l)


def fit_subject(p: Array, l: Array, theta: Array, order: int = FOURIER_ORDER) -> Array:
    """One subject's least-squares model ``xi_q`` (eq. 13) from phase, stride length (m) and angle (deg).

    Raises:
        ValueError: inputs of different lengths, non-finite values, or too few distinct samples.
    """
    p, l, theta = (np.asarray(a, dtype=np.float64).reshape(-1) for a in (p, l, theta))
    if not p.size == l.size == theta.size:
        raise ValueError(f"phase, stride length and angle differ in length: {p.size}, {l.size}, {theta.size}")
    if not (np.isfinite(p).all() and np.isfinite(l).all() and np.isfinite(theta).all()):
        raise ValueError("phase, stride length and angle must be finite")
    A = basis(p, l, order)
    if p.size < A.shape[1] or np.linalg.matrix_rank(A) < A.shape[1]:
        raise ValueError(
            f"{p.size} samples do not determine the {A.shape[1]} model parameters "
            "(walk more strides, at more than one stride length)"
        )
    return np.asarray(np.linalg.lstsq(A, theta, rcond=None)[0], dtype=np.float64)


@dataclass(frozen=True)
class FingerprintMap:
    """The personalization map learnt from training subjects (seed 004 Sec. III).

    Attributes:
        xi_avg: average model ``(c,)`` (eq. 14).
        p_map: ``(k, c)``: ``xi(g) = xi_avg + g @ p_map``; ``g_i = 1`` is a 1 deg RMS change.
        explained: cumulative share of the variance of the subjects' differences in RMSE space, per
            component (Table I), ``(n_subjects - 1,)`` or fewer.
        fit_rmse_deg: each training subject's own-fit RMSE (deg); their mean is ``rbar``.
        gram: ``G`` (eq. 19), kept to measure model differences in deg RMS.
        order: Fourier order of the basis.
        training_g: each training subject's least-squares fingerprint, ``(n_subjects, k)`` (where a new
            person sits among them).
    """

    xi_avg: Array
    p_map: Array
    explained: Array
    fit_rmse_deg: Array
    gram: Array
    order: int = FOURIER_ORDER
    training_g: Array = field(default_factory=lambda: np.zeros((0, 0)))

    @property
    def n_components(self) -> int:
        return int(self.p_map.shape[0])

    @property
    def rbar(self) -> float:
        """Mean own-fit RMSE of the training subjects (deg): the measurement noise's scale."""
        return float(np.mean(self.fit_rmse_deg))

    def xi(self, g: Array) -> Array:
        """The model parameters of fingerprint ``g`` (eq. 10)."""
        return self.xi_avg + np.asarray(g, dtype=np.float64) @ self.p_map

    def rms_deg(self, xi_a: Array, xi_b: Array) -> float:
        """RMS difference (deg) between two models' predictions over the training data (eq. 20)."""
        d = np.asarray(xi_a) - np.asarray(xi_b)
        return math.sqrt(max(float(d @ self.gram @ d), 0.0))

    def ls_fingerprint(self, p: Array, l: Array, theta: Array) -> Array:
        """The least-squares fingerprint (LS-GF) of a walk: ``g`` minimising the angle error (eqs. 36-40).

        Raises:
            ValueError: as :func:`fit_subject`, or a walk that does not determine ``g``.
        """
        p, l, theta = (np.asarray(a, dtype=np.float64).reshape(-1) for a in (p, l, theta))
        if not p.size == l.size == theta.size or p.size == 0:
            raise ValueError(f"phase, stride length and angle differ in length or are empty: {p.size}, {l.size}")
        if not (np.isfinite(p).all() and np.isfinite(l).all() and np.isfinite(theta).all()):
            raise ValueError("phase, stride length and angle must be finite")
        A = basis(p, l, self.order)
        Ap = A @ self.p_map.T
        if np.linalg.matrix_rank(Ap) < self.n_components:
            raise ValueError("the walk does not determine every fingerprint component (too few samples)")
        return np.asarray(np.linalg.lstsq(Ap, theta - A @ self.xi_avg, rcond=None)[0], dtype=np.float64)


def _sqrt_psd(G: Array) -> tuple[Array, Array]:
    """``G^(1/2)`` and ``G^(-1/2)`` of a symmetric positive definite matrix (eq. 26)."""
    lam, O = np.linalg.eigh((G + G.T) / 2.0)
    if lam[0] <= lam[-1] * 1e-12:
        raise ValueError("the training data do not span the basis (Gram matrix singular)")
    return (O * np.sqrt(lam)) @ O.T, (O / np.sqrt(lam)) @ O.T


def fit_map(
    subjects: Sequence[tuple[Array, Array, Array]],
    *,
    variance_threshold: float = 0.99,
    n_components: int | None = None,
    order: int = FOURIER_ORDER,
) -> FingerprintMap:
    """Learn the personalization map from training subjects' ``(phase, stride length m, angle deg)``.

    Per-subject least squares (eq. 13), their average (14) and differences (15); ``G`` over all samples
    (19); differences into RMSE space (30); PCA (31-33) keeping the first components whose cumulative
    variance exceeds ``variance_threshold`` (34), or ``n_components``; ``P_map = U_k^T G^(-1/2)``.

    Raises:
        ValueError: fewer than two subjects, a subject's data that do not determine its model, or a
            threshold outside (0, 1].
    """
    if len(subjects) < 2:
        raise ValueError(f"a map needs at least two training subjects, got {len(subjects)}")
    if not 0.0 < variance_threshold <= 1.0:
        raise ValueError(f"variance_threshold must be in (0, 1], got {variance_threshold}")
    fits, rmse = [], []
    G = np.zeros((2 * (2 * order - 1),) * 2)
    n_total = 0
    for p, l, theta in subjects:
        xi = fit_subject(p, l, theta, order)
        A = basis(p, l, order)
        fits.append(xi)
        rmse.append(float(np.sqrt(np.mean((A @ xi - np.asarray(theta).reshape(-1)) ** 2))))
        G += A.T @ A
        n_total += A.shape[0]
    G /= n_total
    Xi = np.array(fits)
    xi_avg = Xi.mean(axis=0)
    root, inv_root = _sqrt_psd(G)
    X = (Xi - xi_avg) @ root  # rows: each subject's difference in RMSE space (G^(1/2) is symmetric)
    cov = X.T @ X / (len(subjects) - 1)
    psi, U = np.linalg.eigh(cov)
    order_desc = np.argsort(psi)[::-1]
    psi, U = np.clip(psi[order_desc], 0.0, None), U[:, order_desc]
    rank = len(subjects) - 1  # differences from the mean span at most n - 1 directions
    total = float(psi.sum())
    explained = np.cumsum(psi[:rank]) / total if total > 0 else np.ones(rank)
    if n_components is None:
        k = int(np.searchsorted(explained, variance_threshold, side="right")) + 1
        k = min(k, rank)
    else:
        if not 1 <= n_components <= rank:
            raise ValueError(f"n_components must be in 1..{rank} for {len(subjects)} subjects, got {n_components}")
        k = n_components
    p_map = U[:, :k].T @ inv_root
    fmap = FingerprintMap(
        xi_avg=xi_avg, p_map=p_map, explained=explained, fit_rmse_deg=np.array(rmse), gram=G, order=order
    )
    return replace(fmap, training_g=np.array([fmap.ls_fingerprint(*walk) for walk in subjects]))


@dataclass(frozen=True)
class FingerprintConfig:
    """Tuning of :class:`FingerprintEKF` (seed 004 Sec. IV, the authors' code; see the module docstring).

    Attributes:
        q_gf, q_fixed: process noise per step of ``[p, pdot, l, g...]`` (GF) and ``[p, pdot, l]``.
        p0_gf, p0_fixed: initial variances, same layout (``p0_gf`` gives ``g1`` and the rest).
        x0: initial ``[p, pdot, l]``.
        pdot_min_gf, pdot_min_fixed: lower clip of phase rate (1/s).
        l_range_gf, l_range_fixed: clip of stride length (m).
        r_scale: ``R = r_scale diag(rbar^2, rbar^2)``.
        edge: phase distance from heel strike within which ``R`` is inflated by ``edge_scale``.
        edge_scale: factors of the angle and velocity variances there.
    """

    q_gf: tuple[float, ...] = (0.0, 9e-8, 6e-8, 5e-6, 4e-10, 4e-10)
    q_fixed: tuple[float, float, float] = (0.0, 2e-8, 7e-8)
    p0_gf: tuple[float, ...] = (5e-3, 5e-3, 5e-3, 50.0, 5e-5, 5e-5)
    p0_fixed: tuple[float, float, float] = (5e-6, 5e-6, 5e-6)
    x0: tuple[float, float, float] = (0.0, 0.8, 1.2)
    pdot_min_gf: float = 0.8
    pdot_min_fixed: float = 0.5
    l_range_gf: tuple[float, float] = (0.0, 2.0)
    l_range_fixed: tuple[float, float] = (0.8, 2.0)
    r_scale: float = 0.9
    edge: float = 0.05
    edge_scale: tuple[float, float] = (2.0, 10.0)


_PARAMS: Final = ("measurement_noise_scale", "process_noise_scale")
_INPUTS: Final = ("thigh_angle_deg", "thigh_vel_dps")
#: Where :meth:`FingerprintEKF.step` finds each channel in ``z``.
_THIGH, _THIGH_VEL = positions(_INPUTS, "thigh_angle_deg", "thigh_vel_dps")


@dataclass
class FingerprintEKF:
    """The EKF of seed 004 on thigh angle and angular velocity: AVG, LS-GF or GF.

    ``mode``: ``avg`` runs the average model ``xi_avg``; ``ls`` a fixed personal model ``xi(g)`` with
    ``g`` from a calibration walk (:meth:`FingerprintMap.ls_fingerprint`); ``gf`` carries the
    fingerprint in its state, ``x = [p, pdot, l, g_1..g_k]``, started at ``g`` (zeros: the average).
    The dynamics (eqs. 2-3): phase integrates phase rate, the rest are random walks.

    As a stack estimator (:class:`gaitscope.estimators.protocol.Estimator`): inputs thigh angle (deg) and its
    velocity (deg/s); outputs phase, phase rate, stride length (m), the model's thigh angle and, for
    ``gf``, the fingerprint.
    """

    fmap: FingerprintMap
    mode: Mode = "gf"
    g: Array | None = None
    config: FingerprintConfig = field(default_factory=FingerprintConfig)
    name: str = ""
    max_gap_s: float = MAX_GAP_S

    inputs: tuple[str, ...] = _INPUTS
    optional_inputs: tuple[str, ...] = ()
    tunables: tuple[str, ...] = _PARAMS

    def __post_init__(self) -> None:
        if self.mode not in ("avg", "ls", "gf"):
            raise ValueError(f"mode must be avg, ls or gf, got {self.mode!r}")
        k = self.fmap.n_components
        g = np.zeros(k) if self.g is None else np.asarray(self.g, dtype=np.float64).reshape(-1)
        if g.shape != (k,) or not np.isfinite(g).all():
            raise ValueError(f"a fingerprint of this map has {k} finite components, got {g.tolist()}")
        if self.mode == "avg":
            g = np.zeros(k)
        self.g0 = g
        self.name = self.name or {"avg": "fp_avg", "ls": "fp_ls", "gf": "fp_gf"}[self.mode]
        self._xi_fixed = self.fmap.xi(g)
        self._q_scale = 1.0
        self._r_scale = 1.0
        if self.mode == "gf":
            q, p0 = self.config.q_gf, self.config.p0_gf
            self._q = np.array([*q[:3], q[3], *([q[-1]] * (k - 1))]) if len(q) != 3 + k else np.array(q)
            self._p0 = np.array([*p0[:3], p0[3], *([p0[-1]] * (k - 1))]) if len(p0) != 3 + k else np.array(p0)
        else:
            self._q, self._p0 = np.array(self.config.q_fixed), np.array(self.config.p0_fixed)
        self._scale_noise()
        self._t: float | None = None
        self._pending: Array | None = None
        n, c = 3 + (k if self.mode == "gf" else 0), self.fmap.xi_avg.size
        self._work = np.empty(c + c + 3 * n)
        self.reset()

    # --- protocol -------------------------------------------------------------------------------
    @property
    def outputs(self) -> tuple[Output, ...]:
        out: tuple[Output, ...] = (
            ("phase", "1"),
            ("phase_rate", "1/s"),
            ("stride_length_m", "m"),
            ("thigh_pred_deg", "deg"),
        )
        if self.mode == "gf":
            out += tuple((f"g{i + 1}", "deg") for i in range(self.fmap.n_components))
        return out

    @property
    def state(self) -> Array:
        return self.x

    @property
    def covariance(self) -> Array:
        return self.P

    def reset(self) -> None:
        x0 = list(self.config.x0)
        self.x = np.array([*x0, *self.g0]) if self.mode == "gf" else np.array(x0)
        self.P = np.diag(self._p0)
        self._t = None
        self._pred = 0.0

    def retune(self, **params: float) -> None:
        """``measurement_noise_scale`` multiplies ``R``, ``process_noise_scale`` ``Q`` (both > 0)."""
        check_params(self, params)
        for k, v in params.items():
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{k} must be a positive number, got {v}")
        self._r_scale = float(params.get("measurement_noise_scale", self._r_scale))
        self._q_scale = float(params.get("process_noise_scale", self._q_scale))
        self._scale_noise()

    def _scale_noise(self) -> None:
        """The noise a step uses, from the tuning: ``Q`` per step and ``R``'s base variance (once per
        retune, not per sample)."""
        self._q_step = self._q * self._q_scale
        self._r = self.config.r_scale * self.fmap.rbar**2 * self._r_scale
        c, gf = self.config, self.mode == "gf"
        prm = np.zeros(PRM_SIZE)  # the compiled step's constants (_fp_kernel.PRM_*)
        prm[PRM_GF], prm[PRM_R], prm[PRM_EDGE] = 1.0 if gf else 0.0, self._r, c.edge
        prm[PRM_EDGE_A], prm[PRM_EDGE_V] = c.edge_scale[0], c.edge_scale[1]
        prm[PRM_PDOT_MIN] = c.pdot_min_gf if gf else c.pdot_min_fixed
        prm[PRM_L_LO], prm[PRM_L_HI] = c.l_range_gf if gf else c.l_range_fixed
        prm[PRM_ORDER] = self.fmap.order
        self._prm = prm

    def personalize(self, g: Array) -> None:
        """Run fingerprint ``g`` (mode ``ls``) from the next stride on: it takes over when the phase wraps
        (a heel strike), where the thigh is near its largest flexion and a change of model moves the
        prediction least, so that a promotion does not jolt a running filter.

        Raises:
            ValueError: not mode ``ls``, or not a finite fingerprint of this map.
        """
        if self.mode != "ls":
            raise ValueError(f"only the personalized filter takes a new fingerprint, not {self.mode}")
        g = np.asarray(g, dtype=np.float64).reshape(-1)
        if g.shape != (self.fmap.n_components,) or not np.isfinite(g).all():
            raise ValueError(f"a fingerprint of this map has {self.fmap.n_components} finite components")
        self._pending = g

    def step(self, t: float, z: Array) -> Array:
        """One sample: ``z = [thigh angle deg, thigh velocity deg/s]`` (NaN: missing); :meth:`predict` and
        :meth:`update` in one compiled call."""
        if self._pending is not None and self.x[0] + self._t_step(t) * self.x[1] >= 1.0:
            self.g0, self._pending = self._pending, None
            self._xi_fixed = self.fmap.xi(self.g0)
        dt, restart = elapsed(self._t, t, self.max_gap_s)
        if restart:
            self.reset()
        self._t = t
        return fp_stream_step(
            self.x,
            self.P,
            self.fmap.xi_avg,
            self.fmap.p_map,
            self._xi_fixed,
            self._q_step,
            self._prm,
            dt,
            float(z[_THIGH]),
            float(z[_THIGH_VEL]),
            self._work,
        )

    # --- filter ---------------------------------------------------------------------------------
    def predict(self, dt: float) -> None:
        """Phase integrates phase rate over ``dt``; ``Q`` per step (not scaled by ``dt``)."""
        x, P = self.x, self.P
        x[0] = (x[0] + dt * x[1]) % 1.0
        # F P F^T with F = I + dt e0 e1^T, then + Q
        P[0, :] += dt * P[1, :]
        P[:, 0] += dt * P[:, 1]
        P[np.diag_indices_from(P)] += self._q_step

    def _t_step(self, t: float) -> float:
        """The time the next step will predict over (0 on the first sample or after a gap)."""
        if self._t is None or not t - self._t <= self.max_gap_s:
            return 0.0
        return max(t - self._t, 0.0)

    def _xi(self) -> Array:
        return self.fmap.xi(self.x[3:]) if self.mode == "gf" else self._xi_fixed

    def measurement(self) -> tuple[Array, Array]:
        """``h(x)`` (angle, velocity) and its Jacobian ``H`` ``(2, n)`` at the state."""
        x, order = self.x, self.fmap.order
        p, pdot, l = float(x[0]), float(x[1]), float(x[2])
        f, d, d2 = _fourier(np.array([p]), order)
        ls = np.array([l])
        lam, lam_p, lam_pp = _kron_l(f, ls)[0], _kron_l(d, ls)[0], _kron_l(d2, ls)[0]
        # d Lambda / dl: the l-columns carry f, the others 0
        lam_l = np.zeros_like(lam)
        lam_l[1::2] = f[0]
        lam_pl = np.zeros_like(lam)
        lam_pl[1::2] = d[0]
        xi = self._xi()
        h = np.array([lam @ xi, pdot * (lam_p @ xi)])
        H = np.zeros((2, x.size))
        H[0, 0], H[1, 0] = lam_p @ xi, pdot * (lam_pp @ xi)
        H[1, 1] = lam_p @ xi
        H[0, 2], H[1, 2] = lam_l @ xi, pdot * (lam_pl @ xi)
        if self.mode == "gf":
            H[0, 3:] = self.fmap.p_map @ lam
            H[1, 3:] = pdot * (self.fmap.p_map @ lam_p)
        return h, H

    def noise(self, p: float) -> Array:
        """``R`` at phase ``p`` (diagonal of angle and velocity variances)."""
        c, r = self.config, self._r
        ra, rv = r, r
        if p < c.edge or p > 1.0 - c.edge:
            ra, rv = r * c.edge_scale[0], r * c.edge_scale[1]
        return np.array([ra, rv])

    def update(self, z: Array) -> None:
        """Kalman update on the finite entries of ``z``; then phase wrapped, rate and length clipped."""
        z = np.asarray(z, dtype=np.float64)
        h, H = self.measurement()
        ok = np.isfinite(z[:2])
        if ok.any():
            r = self.noise(float(self.x[0]))[ok]
            Hs, y = H[ok], z[:2][ok] - h[ok]
            S = Hs @ self.P @ Hs.T + np.diag(r)
            K = np.linalg.solve(S, Hs @ self.P).T
            self.x = self.x + K @ y
            self.P = self.P - K @ Hs @ self.P
            self.P = (self.P + self.P.T) / 2.0
        c = self.config
        gf = self.mode == "gf"
        lo, hi = c.l_range_gf if gf else c.l_range_fixed
        self.x[0] %= 1.0
        self.x[1] = max(self.x[1], c.pdot_min_gf if gf else c.pdot_min_fixed)
        self.x[2] = min(max(self.x[2], lo), hi)
        self._pred = float(basis(np.array([self.x[0]]), np.array([self.x[2]]), self.fmap.order)[0] @ self._xi())


#: The fingerprint filter's variants: its name in a stack, its name on screen and its role.
_VARIANTS: Final[dict[Mode, tuple[str, str, Literal["average", "personal", "online"]]]] = {
    "avg": ("fp_avg", "Average thigh model (seed 004)", "average"),
    "ls": ("fp_ls", "Personalized thigh model (seed 004 LS-GF)", "personal"),
    "gf": ("fp_gf", "Online fingerprint EKF (seed 004 GF)", "online"),
}
#: What each variant is for, in a line (:attr:`Descriptor.purpose`).
_PURPOSES: Final[dict[Mode, str]] = {
    "avg": "Gait phase and stride length from the thigh angle alone, on the population's average thigh model.",
    "ls": "Gait phase from the thigh angle on the subject's own model: needs a calibrated fingerprint first.",
    "gf": "Gait phase from the thigh angle while it estimates the subject's gait fingerprint live.",
}


def descriptor(mode: Mode, n_components: int = 3) -> Descriptor:
    """The fingerprint filter of ``mode`` as a session and the views know it
    (:mod:`gaitscope.estimators.descriptor`); ``gf`` outputs the ``n_components`` fingerprint components of
    its map (the default model's map keeps 3; a map with another number declares its own)."""
    name, label, role = _VARIANTS[mode]
    outputs: tuple[OutputSpec, ...] = (
        out("phase", "1", "gait phase, 0 at heel strike, 1 at the next"),
        out("phase_rate", "1/s", "gait cycles per second"),
        out("stride_length_m", "m", "stride length"),
        out("thigh_pred_deg", "deg", "the model's thigh angle at the estimated state"),
    )
    if mode == "gf":
        outputs += tuple(out(f"g{i + 1}", "deg", f"fingerprint component {i + 1}") for i in range(n_components))
    return Descriptor(
        name=name,
        label=label,
        inputs=FingerprintEKF.inputs,
        optional_inputs=FingerprintEKF.optional_inputs,
        outputs=outputs,
        quantities={"phase": "phase", "phase_rate": "phase_rate", "stride_length_m": "stride_length"},
        tunables=tuple(Tunable(p) for p in FingerprintEKF.tunables),
        fingerprint=role,
        live=tuple(o.name for o in outputs[4:]),  # the online fingerprint, which the subject page draws moving
        purpose=_PURPOSES[mode],
        paper="Montes Pérez, Thomas and Gregg (seed 004)",
    )

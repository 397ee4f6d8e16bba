"""Sparse Gaussian-process regression (FITC) for seed 003's observation models and control surfaces.

Seed 003 (section II-A) regresses each joint angle and each joint velocity (in ``d theta / d phi``) on the
stance phase with a sparse GP, the fully independent training conditional (FITC) with 25 active points,
and its control surfaces on (phase, phase rate) with 100 (II-B). The kernel and its hyperparameters are not
given; gaitscope takes an RBF kernel (one lengthscale per input) with maximum-likelihood hyperparameters
(``shared/reference/estimators.md`` section 3).

Fitting uses GPy (:func:`fit_gpy`: ``GPy.core.SparseGP`` with ``inference_method=FITC()``, the targets
standardized, the inducing inputs started deterministically, from the quantiles of a 1-D input or by
farthest-point sampling of a 2-D one, and optimized with the hyperparameters by L-BFGS-B). What a fit
leaves is frozen into :class:`SparseGP`, whose prediction is pure numpy: the mean, its analytic derivative
(Solak et al. 2003; for the RBF ``d/dx k(x, u) = -(x - u) / ell^2 k(x, u)``) and the predictive variance
including the noise (GPy's ``predict``, which is the EKF's measurement noise). :class:`GPStack` evaluates
several 1-D GPs at one input in one compiled call (:func:`stack_eval`, numba), the GP-EKF's per-sample
hot path. GPy is imported only to fit.

With ``rho_m(x) = exp(-|x - z_m|^2 / (2 ell^2))`` (per-dimension lengthscales) a model is::

    mean(x) = offset + sum_m a_m rho_m(x)
    var(x)  = max(variance - rho(x)^T W rho(x), 1e-15) + noise

where ``a = s sigma_f^2 v`` and ``W = s^2 sigma_f^4 (Kmm^-1 - P)`` fold GPy's woodbury vector ``v`` and
woodbury inverse, the RBF variance ``sigma_f^2`` and the standardization scale ``s`` into output units.

Its compiled kernels are cached on disk by numba (``cache=True``) under ``gaitscope.estimators.gp``: a cache
written when the folder was imported as plain ``estimators`` (before issue #22) names that module and is
dropped, since this file changed with the move."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import ArrayLike, NDArray

__all__ = ["FitOptions", "GPStack", "SparseGP", "fit_gpy", "fit_sparse_gp", "from_gpy", "rbf_mean_2d", "stack_eval"]

Array = NDArray[np.float64]
#: GPy's floor on the latent predictive variance (``Posterior._raw_predict``).
_MIN_LATENT_VARIANCE = 1e-15


@dataclass(frozen=True)
class FitOptions:
    """How :func:`fit_gpy` fits a sparse GP.

    Attributes:
        n_inducing: inducing (active) points, seed 003: 25 for the observation models, 100 for the
            control surfaces (at most the number of distinct inputs).
        max_iters: L-BFGS-B function evaluations at most.
        optimize_inducing: optimize the inducing inputs with the hyperparameters (SPGP's pseudo-inputs,
            Snelson and Ghahramani 2006). False (default) keeps them where they start, at training inputs:
            seed 003 speaks of "a fixed-size active set of training points"; it is also 4-5 times faster
            (about 20 evaluations to converge instead of the 100 cap) and never drives a lengthscale to 0.
        init_lengthscale: the starting lengthscale of each input as a fraction of its range.
        init_noise: the starting noise variance as a fraction of the (standardized) target variance.
        max_points: fit on at most this many samples, evenly spaced in the order given (None: all). FITC
            costs ``O(n M^2)`` per evaluation.
        blas_threads: BLAS threads during the fit (None: leave BLAS alone). The fit's matrices are small
            (``n x 25``), and on two cores OpenBLAS's threads make it ten times slower, not faster.
    """

    n_inducing: int = 25
    max_iters: int = 200
    optimize_inducing: bool = False
    init_lengthscale: float = 0.15
    init_noise: float = 0.05
    max_points: int | None = 2000
    blas_threads: int | None = 1

    def __post_init__(self) -> None:
        if self.n_inducing < 1 or self.max_iters < 0 or not (self.init_lengthscale > 0 and self.init_noise > 0):
            raise ValueError(f"n_inducing >= 1, max_iters >= 0, positive initial values: {self}")
        if self.max_points is not None and self.max_points < 2:
            raise ValueError(f"max_points must be at least 2, got {self.max_points}")


@dataclass(frozen=True, eq=False)
class SparseGP:
    """A fitted sparse GP with an RBF kernel, frozen for prediction (module docstring for the formulas).

    Attributes:
        Z: inducing inputs ``(M, d)``.
        lengthscale: ``(d,)``, in input units.
        variance: signal variance ``s^2 sigma_f^2`` (output units squared).
        noise: noise variance (output units squared).
        alpha: ``(M,)`` woodbury vector in output units (``a``).
        w_inv: ``(M, M)`` woodbury inverse in output units squared (``W``), symmetric.
        offset: the output mean the targets were standardized by.
    """

    Z: Array
    lengthscale: Array
    variance: float
    noise: float
    alpha: Array
    w_inv: Array
    offset: float

    def __post_init__(self) -> None:
        m, d = self.Z.shape
        if self.lengthscale.shape != (d,) or self.alpha.shape != (m,) or self.w_inv.shape != (m, m):
            raise ValueError(
                f"inconsistent shapes: Z {self.Z.shape}, lengthscale {self.lengthscale.shape}, "
                f"alpha {self.alpha.shape}, w_inv {self.w_inv.shape}"
            )
        if not (self.variance > 0 and self.noise > 0 and np.all(self.lengthscale > 0)):
            raise ValueError("variance, noise and lengthscales must be positive")

    @property
    def input_dim(self) -> int:
        return int(self.Z.shape[1])

    @property
    def n_inducing(self) -> int:
        return int(self.Z.shape[0])

    def _inputs(self, x: ArrayLike) -> Array:
        x = np.asarray(x, dtype=np.float64)
        if self.input_dim == 1 and x.ndim <= 1:
            return x.reshape(-1, 1)
        if x.ndim == 1 and x.shape[0] == self.input_dim:
            return x.reshape(1, -1)
        if x.ndim != 2 or x.shape[1] != self.input_dim:
            raise ValueError(f"inputs must have shape (n, {self.input_dim}), got {x.shape}")
        return x

    def _rho(self, x: Array) -> tuple[Array, Array]:
        """Scaled differences ``(x - z) / ell^2`` ``(n, M, d)`` and ``rho`` ``(n, M)``."""
        diff = x[:, None, :] - self.Z[None, :, :]
        r2 = np.sum((diff / self.lengthscale) ** 2, axis=2)
        return diff / self.lengthscale**2, np.exp(-0.5 * r2)

    def mean(self, x: ArrayLike) -> Array:
        """The predictive mean at ``x`` (``(n,)`` or ``(n, d)``): ``(n,)``."""
        _, rho = self._rho(self._inputs(x))
        return self.offset + rho @ self.alpha

    def gradient(self, x: ArrayLike) -> Array:
        """The mean's analytic gradient ``d mean / d x`` ``(n, d)``."""
        scaled, rho = self._rho(self._inputs(x))
        return -np.einsum("nmd,nm,m->nd", scaled, rho, self.alpha)

    def derivative(self, x: ArrayLike) -> Array:
        """``d mean / d x`` of a 1-D GP ``(n,)``."""
        if self.input_dim != 1:
            raise ValueError("derivative is for a 1-D input; use gradient")
        return self.gradient(x)[:, 0]

    def variance_at(self, x: ArrayLike, noise: bool = True) -> Array:
        """The predictive variance ``(n,)``, with the noise (GPy's ``predict``) or without
        (``predict_noiseless``)."""
        _, rho = self._rho(self._inputs(x))
        latent = np.maximum(self.variance - np.einsum("ni,ij,nj->n", rho, self.w_inv, rho), _MIN_LATENT_VARIANCE)
        return latent + self.noise if noise else latent

    def predict(self, x: ArrayLike) -> tuple[Array, Array]:
        """``(mean, variance)`` with the noise, as GPy's ``model.predict`` (flattened)."""
        return self.mean(x), self.variance_at(x)

    def to_arrays(self) -> dict[str, Array]:
        """Plain arrays (for ``np.savez``; :meth:`from_arrays` reads them back exactly)."""
        return {
            "Z": self.Z,
            "lengthscale": self.lengthscale,
            "alpha": self.alpha,
            "w_inv": self.w_inv,
            "scalars": np.array([self.variance, self.noise, self.offset]),
        }

    @classmethod
    def from_arrays(cls, arrays: dict[str, Array]) -> SparseGP:
        variance, noise, offset = (float(v) for v in arrays["scalars"])
        return cls(
            Z=np.array(arrays["Z"], dtype=np.float64),
            lengthscale=np.array(arrays["lengthscale"], dtype=np.float64),
            variance=variance,
            noise=noise,
            alpha=np.array(arrays["alpha"], dtype=np.float64),
            w_inv=np.array(arrays["w_inv"], dtype=np.float64),
            offset=offset,
        )


# --- fitting (GPy) ------------------------------------------------------------------------------------
def _initial_inducing(x: Array, m: int) -> Array:
    """Deterministic inducing inputs at training inputs: the nearest to evenly spaced quantiles of a 1-D
    input; farthest-point sampling of a standardized multi-dimensional one, from the sample nearest the
    mean."""
    if x.shape[1] == 1:
        return np.quantile(x[:, 0], np.linspace(0.0, 1.0, m), method="nearest").reshape(-1, 1)
    u = (x - x.mean(axis=0)) / np.where(x.std(axis=0) > 0, x.std(axis=0), 1.0)
    chosen = [int(np.argmin(np.sum(u * u, axis=1)))]
    dist = np.sum((u - u[chosen[0]]) ** 2, axis=1)
    for _ in range(m - 1):
        k = int(np.argmax(dist))
        chosen.append(k)
        dist = np.minimum(dist, np.sum((u - u[k]) ** 2, axis=1))
    return x[np.array(chosen)].copy()


def _training_arrays(x: ArrayLike, y: ArrayLike, options: FitOptions) -> tuple[Array, Array]:
    X = np.asarray(x, dtype=np.float64)
    X = X.reshape(-1, 1) if X.ndim == 1 else X
    Y = np.asarray(y, dtype=np.float64).reshape(-1, 1)
    if X.ndim != 2 or X.shape[0] != Y.shape[0]:
        raise ValueError(f"inputs (n, d) and targets (n,) differ: {X.shape}, {Y.shape}")
    if X.shape[0] < 2 or not (np.isfinite(X).all() and np.isfinite(Y).all()):
        raise ValueError("a fit needs at least two samples, all finite")
    if options.max_points is not None and X.shape[0] > options.max_points:
        keep = np.unique(np.round(np.linspace(0, X.shape[0] - 1, options.max_points)).astype(np.int64))
        X, Y = X[keep], Y[keep]
    if not float(np.std(Y)) > 1e-12 * max(1.0, float(np.max(np.abs(Y)))):
        raise ValueError("the targets are constant: nothing to regress")
    return X, Y


def fit_gpy(x: ArrayLike, y: ArrayLike, options: FitOptions | None = None, Z: ArrayLike | None = None) -> Any:
    """Fit a FITC sparse GP with an RBF kernel by maximum likelihood; returns the GPy model.

    Args:
        x: inputs ``(n,)`` or ``(n, d)``.
        y: targets ``(n,)``, standardized for the fit (GPy's ``Standardize`` normalizer).
        options: see :class:`FitOptions`.
        Z: the starting inducing inputs ``(M, d)`` (default: :func:`_initial_inducing`).

    Raises:
        ValueError: fewer than two samples, a non-finite one, or constant targets.
    """
    options = options or FitOptions()
    if options.blas_threads is None:
        return _fit(x, y, options, Z)
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=options.blas_threads, user_api="blas"):
        return _fit(x, y, options, Z)


def _fit(x: ArrayLike, y: ArrayLike, options: FitOptions, Z: ArrayLike | None) -> Any:
    import GPy  # only fitting needs it (its import takes seconds)
    import GPy.kern.src.stationary

    # GPy's Cython kernel gradients are 4 times slower than its numpy ones at these sizes (the inducing
    # inputs' gradient is computed even when they are fixed); both give the same numbers.
    GPy.kern.src.stationary.use_stationary_cython = False

    X, Y = _training_arrays(x, y, options)
    d = X.shape[1]
    if Z is None:
        Zi = _initial_inducing(X, min(options.n_inducing, X.shape[0]))
    else:
        Zi = np.array(Z, dtype=np.float64).reshape(-1, d)
    span = np.ptp(X, axis=0)
    ell = options.init_lengthscale * np.where(span > 0, span, 1.0)
    kernel = GPy.kern.RBF(d, variance=1.0, lengthscale=ell, ARD=d > 1)
    likelihood = GPy.likelihoods.Gaussian(variance=options.init_noise)
    fitc = GPy.inference.latent_function_inference.FITC()
    model = GPy.core.SparseGP(X, Y, Zi, kernel, likelihood, inference_method=fitc, normalizer=True)
    if not options.optimize_inducing:
        model.Z.fix()
    if options.max_iters > 0:
        with np.errstate(over="ignore", under="ignore", invalid="ignore", divide="ignore"):
            model.optimize(max_iters=options.max_iters)  # L-BFGS-B steps back from a non-finite trial point
    return model


def from_gpy(model: Any) -> SparseGP:
    """Freeze a fitted GPy sparse (or exact) GP with an RBF kernel and a Gaussian likelihood."""
    kern = model.kern
    d = int(model.X.shape[1])
    sf2 = float(kern.variance.values[0])
    norm = model.normalizer
    mean, std = (float(norm.mean[0]), float(norm.std[0])) if norm is not None else (0.0, 1.0)
    Z = np.array(model.Z.values if hasattr(model, "Z") else model.X, dtype=np.float64)
    w = np.array(model.posterior.woodbury_inv, dtype=np.float64)
    return SparseGP(
        Z=Z,
        lengthscale=np.broadcast_to(np.array(kern.lengthscale.values, dtype=np.float64), (d,)).copy(),
        variance=std * std * sf2,
        noise=std * std * float(model.likelihood.variance.values[0]),
        alpha=std * sf2 * np.array(model.posterior.woodbury_vector, dtype=np.float64)[:, 0],
        w_inv=std * std * sf2 * sf2 * 0.5 * (w + w.T),
        offset=mean,
    )


def fit_sparse_gp(x: ArrayLike, y: ArrayLike, options: FitOptions | None = None) -> SparseGP:
    """:func:`fit_gpy` then :func:`from_gpy`."""
    return from_gpy(fit_gpy(x, y, options))


# --- compiled prediction ------------------------------------------------------------------------------
#: Columns of :attr:`GPStack.par`.
_IL2, _VAR, _NOISE, _OFFSET, _COUNT = range(5)


@njit(cache=True)
def stack_eval(
    x: float, Z: Array, A: Array, W: Array, par: Array, rho: Array, mu: Array, dmu: Array, var: Array
) -> None:
    """Mean, mean derivative and predictive variance (with noise) of G stacked 1-D GPs at one input.

    Args:
        x: the input.
        Z, A: ``(G, M)`` inducing inputs and woodbury vectors, zero-padded past each GP's count.
        W: ``(G, M, M)`` woodbury inverses, zero-padded.
        par: ``(G, 5)``: ``1 / ell^2``, variance, noise, offset, inducing count.
        rho: ``(M,)`` scratch.
        mu, dmu, var: ``(G,)`` written.
    """
    for g in range(Z.shape[0]):
        n = int(par[g, _COUNT])
        il2 = par[g, _IL2]
        m = 0.0
        dm = 0.0
        for j in range(n):
            d = x - Z[g, j]
            r = np.exp(-0.5 * d * d * il2)
            rho[j] = r
            ra = r * A[g, j]
            m += ra
            dm -= d * il2 * ra
        q = 0.0
        for i in range(n):  # rho^T W rho over the upper triangle (W is symmetric)
            ri = rho[i]
            s = 0.5 * W[g, i, i] * ri
            for j in range(i + 1, n):
                s += W[g, i, j] * rho[j]
            q += ri * s
        mu[g] = par[g, _OFFSET] + m
        dmu[g] = dm
        var[g] = max(par[g, _VAR] - 2.0 * q, _MIN_LATENT_VARIANCE) + par[g, _NOISE]


@njit(cache=True)
def rbf_mean_2d(x0: float, x1: float, Z: Array, inv_ell2: Array, alpha: Array, offset: float) -> float:
    """The mean of one GP of two inputs at ``(x0, x1)``: ``Z`` ``(M, 2)``, ``inv_ell2`` ``(2,)``."""
    out = offset
    for j in range(Z.shape[0]):
        d0 = x0 - Z[j, 0]
        d1 = x1 - Z[j, 1]
        out += alpha[j] * np.exp(-0.5 * (d0 * d0 * inv_ell2[0] + d1 * d1 * inv_ell2[1]))
    return out


class GPStack:
    """Several 1-D :class:`SparseGP` evaluated together at one input (:meth:`evaluate`, compiled).

    Attributes:
        gps: the GPs, in output order.
        Z, A, W, par: the packed arrays of :func:`stack_eval`.
    """

    def __init__(self, gps: Sequence[SparseGP]):
        if not gps or any(g.input_dim != 1 for g in gps):
            raise ValueError("a stack needs at least one GP, each of one input")
        self.gps = tuple(gps)
        G, M = len(gps), max(g.n_inducing for g in gps)
        self.Z = np.zeros((G, M))
        self.A = np.zeros((G, M))
        self.W = np.zeros((G, M, M))
        self.par = np.zeros((G, 5))
        for i, g in enumerate(gps):
            m = g.n_inducing
            self.Z[i, :m] = g.Z[:, 0]
            self.A[i, :m] = g.alpha
            self.W[i, :m, :m] = g.w_inv
            self.par[i] = (1.0 / g.lengthscale[0] ** 2, g.variance, g.noise, g.offset, m)
        self._rho = np.zeros(M)

    def __len__(self) -> int:
        return len(self.gps)

    def evaluate(self, x: float, mu: Array, dmu: Array, var: Array) -> None:
        """Mean, mean derivative and predictive variance (with noise) of every GP at ``x``, into the
        ``(G,)`` arrays given."""
        stack_eval(float(x), self.Z, self.A, self.W, self.par, self._rho, mu, dmu, var)

"""Seed 003's GP-EKF observation models (:mod:`gaitscope.estimators.gp_ekf`): the training windows the filter
offers, the model sets fitted to them, and the check a new set passes before it replaces the one in use.

A :class:`TrainingWindow` holds completed stances labelled in hindsight (``phi = t / T_n``, ``phidot =
1 / T_n``); :func:`fit_models` fits a :class:`GPModelSet` (six FITC GPs, :mod:`gaitscope.estimators.gp`) to all of
its stances but the last, anywhere (the live server fits in a worker process); :func:`check_models`
judges a new set on the held-out stance against the set in use. Pure numpy, no state.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gaitscope.estimators.gp import FitOptions, GPStack, SparseGP, fit_sparse_gp

if TYPE_CHECKING:
    from gaitscope.estimators.gp_ekf import GPEKFConfig

__all__ = [
    "CHANNEL_NAMES",
    "JOINTS",
    "GPModelSet",
    "TrainingWindow",
    "check_models",
    "fit_models",
    "heldout_rmse",
]

Array = NDArray[np.float64]
JOINTS: Final = ("hip", "knee", "ankle")
#: The six measurement channels, in ``z`` order.
CHANNEL_NAMES: Final = (*(f"{j} angle" for j in JOINTS), *(f"{j} velocity" for j in JOINTS))


# --- data ---------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class TrainingWindow:
    """Stance samples with their hindsight labels, one row per sample.

    Attributes:
        index: 0 for a population data set, else the filter's window number (1, 2, ...): the version of
            the models fitted to it.
        t: ``(n,)`` sample times (s).
        step: ``(n,)`` the completed stance each sample belongs to (the filter's count; the last one is
            held out of the fit).
        phase, phase_rate: ``(n,)`` hindsight labels ``t / T_n`` and ``1 / T_n``.
        angle, velocity: ``(n, 3)`` hip, knee, ankle (deg, deg/s); NaN where the channel was missing.
        moment: ``(n,)`` plantarflexor moment (N m/kg) for a control surface, or None.
    """

    index: int
    t: Array
    step: NDArray[np.int64]
    phase: Array
    phase_rate: Array
    angle: Array
    velocity: Array
    moment: Array | None = None

    @property
    def steps(self) -> tuple[int, int]:
        """First and last stance."""
        return int(self.step[0]), int(self.step[-1])

    @property
    def span(self) -> tuple[float, float]:
        """First and last sample time (s)."""
        return float(self.t[0]), float(self.t[-1])

    @property
    def heldout(self) -> NDArray[np.bool_]:
        """The last stance's samples: never fitted, used to check a fit."""
        return self.step == self.step[-1]

    @property
    def z(self) -> Array:
        """``(n, 6)``: angles then velocities, the filter's measurement order."""
        return np.concatenate([self.angle, self.velocity], axis=1)


# --- models -------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class GPModelSet:
    """One version of the observation models: a GP per joint angle and per ``dtheta/dphi``.

    Attributes:
        version: 0 the population model; else the number of the window it was fitted to.
        angle, velocity: hip, knee, ankle GPs over the stance phase (deg; deg per unit phase).
        span, steps: the training window's time span (s) and stances (the population model's: the cohort
            table's times and stride numbers).
        rmse: ``(6,)`` fit quality: RMSE on the window's held-out stance per channel (deg, deg/s).
        window: the data it was fitted to (None for a loaded model), kept so a review can refit it.
        unfit: channels the window could not fit (no two finite, varying samples); their GP is a flat
            placeholder and :func:`check_models` refuses the set.
    """

    version: int
    angle: tuple[SparseGP, ...]
    velocity: tuple[SparseGP, ...]
    span: tuple[float, float]
    steps: tuple[int, int]
    rmse: Array
    window: TrainingWindow | None = field(default=None, repr=False)
    unfit: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if len(self.angle) != 3 or len(self.velocity) != 3:
            raise ValueError("a model set has three angle and three velocity GPs (hip, knee, ankle)")

    @functools.cached_property
    def stack(self) -> GPStack:
        """The six GPs stacked in measurement order for the compiled update."""
        return GPStack([*self.angle, *self.velocity])

    def predict(self, phase: ArrayLike, phase_rate: ArrayLike) -> tuple[Array, Array]:
        """The measurement model ``h(x)`` ``(n, 6)`` and its noise ``diag(M R M^T)`` ``(n, 6)`` at states."""
        p = np.clip(np.asarray(phase, dtype=np.float64).reshape(-1), 0.0, 1.0)
        r = np.broadcast_to(np.asarray(phase_rate, dtype=np.float64).reshape(-1), p.shape)
        h = np.stack([g.mean(p) for g in self.angle] + [g.mean(p) * r for g in self.velocity], axis=1)
        var = np.stack([g.variance_at(p) for g in self.angle] + [g.variance_at(p) * r * r for g in self.velocity], 1)
        return h, var

    def to_arrays(self) -> dict[str, Array]:
        """Plain arrays for ``np.savez`` (:meth:`from_arrays`; the window is not kept)."""
        out = {"meta": np.array([self.version, *self.span, *self.steps], dtype=np.float64), "rmse": self.rmse}
        for kind, gps in (("angle", self.angle), ("velocity", self.velocity)):
            for j, g in enumerate(gps):
                out.update({f"{kind}{j}.{k}": v for k, v in g.to_arrays().items()})
        return out

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, Array]) -> GPModelSet:
        meta = np.asarray(arrays["meta"], dtype=np.float64)

        def gps(kind: str) -> tuple[SparseGP, ...]:
            keys = ("Z", "lengthscale", "alpha", "w_inv", "scalars")
            return tuple(SparseGP.from_arrays({k: arrays[f"{kind}{j}.{k}"] for k in keys}) for j in range(3))

        return cls(
            version=int(meta[0]),
            angle=gps("angle"),
            velocity=gps("velocity"),
            span=(float(meta[1]), float(meta[2])),
            steps=(int(meta[3]), int(meta[4])),
            rmse=np.array(arrays["rmse"], dtype=np.float64),
        )


def heldout_rmse(models: GPModelSet, window: TrainingWindow) -> Array:
    """RMSE per channel ``(6,)`` of ``models`` at the hindsight labels of the window's held-out stance (NaN
    where that channel has no sample there)."""
    m = window.heldout
    h, _ = models.predict(window.phase[m], window.phase_rate[m])
    e = window.z[m] - h
    ok = np.isfinite(e)
    return np.array([math.sqrt(float(np.mean(e[ok[:, i], i] ** 2))) if ok[:, i].any() else math.nan for i in range(6)])


def fit_models(window: TrainingWindow, options: FitOptions | None = None) -> GPModelSet:
    """Fit the six observation GPs to the window's stances but its last (pure; run it anywhere).

    The velocity GPs regress ``thetadot / phidot = thetadot T_n``. The result's version is
    ``window.index`` and its :attr:`GPModelSet.rmse` the held-out RMSE. A channel without two finite,
    varying training samples gets a flat placeholder and is named in :attr:`GPModelSet.unfit`.

    Raises:
        ValueError: the window has a single stance (nothing is left once it is held out).
    """
    train = ~window.heldout
    if not train.any():
        raise ValueError("the window has one stance: nothing left to fit once it is held out")
    gps: list[SparseGP] = []
    unfit: list[str] = []
    for i, name in enumerate(CHANNEL_NAMES):
        y = window.z[:, i] if i < 3 else window.z[:, i] / window.phase_rate
        ok = train & np.isfinite(y)
        try:
            gps.append(fit_sparse_gp(window.phase[ok], y[ok], options))
        except ValueError:  # too few samples, or constant ones
            unfit.append(name)
            level = float(np.mean(y[ok])) if ok.any() else 0.0
            gps.append(SparseGP(np.full((1, 1), 0.5), np.ones(1), 1.0, 1e6, np.zeros(1), np.zeros((1, 1)), level))
    models = GPModelSet(
        window.index, tuple(gps[:3]), tuple(gps[3:]), window.span, window.steps, np.zeros(6), window, tuple(unfit)
    )
    return replace(models, rmse=heldout_rmse(models, window))


def check_models(new: GPModelSet, current: GPModelSet, config: GPEKFConfig) -> str:
    """Why ``new`` must not replace ``current`` ('' when it may), judged on ``new``'s window.

    Refused when (1) a channel is present in less than ``min_coverage`` of the window's samples or of its
    held-out stance's, or could not be fitted (a lost or stuck sensor); (2) a stance lasted more than
    ``max_stance_ratio`` times the window's median or less than its inverse (a stop within a stance, or a
    missed event: its hindsight labels are wrong); (3) on the held-out stance a channel's RMSE with ``new``
    exceeds ``rmse_ratio`` times ``current``'s plus ``angle_tolerance_deg`` (angles) or
    ``velocity_tolerance_dps`` (velocities). (3) alone cannot tell a stop: the models follow the speed
    through the training window, and on the cohort's sinusoidal speed a clean refit's held-out RMSE is
    0.2 to 1.8 times its predecessor's (geometric mean over the channels), a refit on a window with a
    3 s stop in one stance 0.6 to 7.5 times.
    """
    w = new.window
    if w is None:
        return f"version {new.version} has no training window to check it on"
    z = np.isfinite(w.z)
    for i, name in enumerate(CHANNEL_NAMES):
        if name in new.unfit:
            return f"{name} could not be fitted (no varying data)"
        for where, rows in (("window", z[:, i]), ("held-out stance", z[w.heldout, i])):
            if rows.mean() < config.min_coverage:
                need = 100 * config.min_coverage
                return f"{name} present in {100 * rows.mean():.0f}% of the {where} (needs {need:.0f}%)"
    _, first = np.unique(w.step, return_index=True)
    T = 1.0 / w.phase_rate[first]
    ratio = T / float(np.median(T))
    k = int(np.argmax(np.maximum(ratio, 1.0 / ratio)))
    if max(ratio[k], 1.0 / ratio[k]) > config.max_stance_ratio:
        return f"stance {int(w.step[first[k]])} lasted {T[k]:.2f} s, the window's median {np.median(T):.2f} s"
    old = heldout_rmse(current, w)
    for i, name in enumerate(CHANNEL_NAMES):
        tol = config.angle_tolerance_deg if i < 3 else config.velocity_tolerance_dps
        if not new.rmse[i] <= config.rmse_ratio * old[i] + tol:  # NaN refuses
            unit = "deg" if i < 3 else "deg/s"
            return (
                f"{name}: held-out RMSE {new.rmse[i]:.2f} {unit} with version {new.version}, "
                f"{old[i]:.2f} with version {current.version}"
            )
    return ""

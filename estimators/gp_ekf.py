"""Seed 003's GP-EKF: stance phase and phase rate from joint angles and velocities, retrained online.

Thatte, Shah and Geyer 2019 (``shared/seeds/003_*.txt`` section II; digest section 3). State
``x = [phi, phidot]``: stance phase (0 at heel strike, 1 at toe-off) and its rate (1/s). Per sample:

- predict (eq. 1): ``x = A x``, ``A = [[1, dt], [0, 1]]``, ``P = A P A^T + Q``, ``Q = diag(0, q dt / 0.01 s)``
  with the paper's ``q = 1e-7`` per 10 ms sample (gaitscope scales it to the actual ``dt``);
- update (eq. 2-9, Ko and Fox's GP-EKF) with ``z = [theta_hip, theta_knee, theta_ankle, thetadot_*]`` (deg,
  deg/s): ``h = [GP_mu^theta(phi), GP_mu^{dtheta/dphi}(phi) phidot]``, angle rows of ``H`` ``[GP', 0]``,
  velocity rows ``[phidot GP^{dtheta/dphi}', GP^{dtheta/dphi}]``, ``R = M diag(GP_sigma^2) M^T`` with
  ``M = blkdiag(I3, phidot I3)``; a NaN entry of ``z`` is a missing channel, left out of the update;
- at each heel strike (eq. 10): ``x = [0, 1 / T_(n-1)]``, ``P = 0``.

The GPs (:mod:`gaitscope.estimators.gp`, FITC, 25 inducing points) are trained on each completed stance's samples
labelled in hindsight, ``phi = t / T_n`` and ``phidot = 1 / T_n`` (``T_n`` the stance's duration), the
velocity GPs on ``thetadot T_n = dtheta/dphi``. Every ``retrain_every`` (5) completed stances the filter
offers a :class:`TrainingWindow`; a caller fits it anywhere with :func:`fit_models` and hands the result
back with :meth:`GPEKF.offer`, which checks it on the window's held-out last stance (:func:`check_models`)
before the filter installs it at the next heel strike. Versions, freeze and rollback: :class:`GPEKF`.

Choices where the paper is silent (each a :class:`GPEKFConfig` field; ``docs/estimators.md``):

- toe-off: ``"knee"`` (default), the peak of the knee's flexion velocity in late stance (armed after
  ``toe_off_earliest`` of the previous stance, above ``toe_off_knee_dps``, taken when the velocity has
  fallen ``toe_off_drop`` below its peak and dated at the peak); on the cohort it lies within -67..+27 ms
  of toe-off from 0.4 to 1.6 m/s, where peak ankle plantarflexion velocity leads by up to 150 ms at slow
  speeds. ``"phase"``: the filter's phase reaching 1 (self-referential labels). Either way a phase held at
  1 for ``toe_off_overdue`` of the previous stance ends the stance (dated when it reached 1);
- swing (after toe-off): the phase holds at 1, the rate at its last stance value, no updates, no data;
- ``T_(n-1)`` is the last stance within ``max_stance_ratio`` of the one before (or two alike in a row):
  a stance with a stop in it does not time the next;
- first model: a population model fitted to the virtual cohort's stances
  (:func:`gaitscope.estimators.gp_ekf_estimator.cohort_stances`, :func:`fit_models`), version 0;
- the training window is the last ``window_steps`` completed stances (the paper's set accumulates; a
  live session must bound fit time and memory), its last stance held out of the fit;
- the phase is kept in [0, 1] and the rate in [0, ``max_phase_rate``] after each step; ``velocity_noise_floor``
  (deg/s)^2 is added to the velocity rows' noise (the differentiated encoders' own noise, which keeps ``S``
  invertible at ``phidot = 0``).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numba import njit
from numpy.typing import NDArray

from gaitscope.estimators.gp import stack_eval
from gaitscope.estimators.gp_models import GPModelSet, TrainingWindow, check_models

__all__ = [
    "GPEKF",
    "GPEKFConfig",
    "Installed",
    "Offer",
]

Array = NDArray[np.float64]
#: Bits of :meth:`GPEKF.step`'s return value: a heel strike, a toe-off, a non-finite state reset.
HEEL_STRIKE, TOE_OFF, DIVERGED = 1, 2, 4


@dataclass(frozen=True)
class GPEKFConfig:
    """Tuning and the choices of :class:`GPEKF` (module docstring); defaults are the paper's where it
    gives them.

    Attributes:
        q_phase_rate: ``Q[1, 1]`` per ``q_time_unit`` (paper: 1e-7 per 10 ms sample); ``Q[0, 0] = 0``.
        q_time_unit: the time (s) over which ``q_phase_rate`` accrues; ``Q`` scales with ``dt / q_time_unit``.
        velocity_noise_floor: (deg/s)^2 added to each velocity row of ``R`` (not in the paper).
        measurement_noise_scale: multiplies ``R`` (1: the paper).
        max_phase_rate: the rate is kept in [0, this] (1/s).
        initial_stance_s: ``T_(n-1)`` before the first completed stance.
        min_stance_s, max_stance_s: a stance outside these is neither learnt from nor timed by.
        toe_off: ``"knee"`` or ``"phase"`` (module docstring).
        toe_off_earliest: no knee toe-off before this fraction of ``T_(n-1)`` after the heel strike.
        toe_off_knee_dps: the knee flexion velocity's peak must exceed this (deg/s).
        toe_off_drop: the peak is taken once the velocity is this fraction below it.
        toe_off_overdue: a phase at 1 for this fraction of ``T_(n-1)`` ends the stance anyway.
        retrain_every: completed stances between training windows (paper: 5).
        window_steps: stances in a window (the last one held out).
        keep_versions: installs kept for rollback and review.
        min_coverage, max_stance_ratio, rmse_ratio, angle_tolerance_deg, velocity_tolerance_dps: the
            check before an install (:func:`check_models`).
    """

    q_phase_rate: float = 1e-7
    q_time_unit: float = 0.01
    velocity_noise_floor: float = 4.0
    measurement_noise_scale: float = 1.0
    max_phase_rate: float = 5.0
    initial_stance_s: float = 0.7
    min_stance_s: float = 0.2
    max_stance_s: float = 4.0
    toe_off: Literal["knee", "phase"] = "knee"
    toe_off_earliest: float = 0.4
    toe_off_knee_dps: float = 50.0
    toe_off_drop: float = 0.15
    toe_off_overdue: float = 0.3
    retrain_every: int = 5
    window_steps: int = 5
    keep_versions: int = 8
    max_stance_ratio: float = 1.5
    rmse_ratio: float = 2.0
    angle_tolerance_deg: float = 1.0
    velocity_tolerance_dps: float = 10.0
    min_coverage: float = 0.9

    def __post_init__(self) -> None:
        if self.toe_off not in ("knee", "phase"):
            raise ValueError(f"toe_off must be 'knee' or 'phase', got {self.toe_off!r}")
        if not (0 < self.min_stance_s < self.initial_stance_s < self.max_stance_s):
            raise ValueError("stance durations must satisfy 0 < min < initial < max")
        if self.retrain_every < 1 or self.window_steps < 2 or self.keep_versions < 1:
            raise ValueError("retrain_every >= 1, window_steps >= 2 (one is held out), keep_versions >= 1")
        if not (self.q_phase_rate >= 0 and self.q_time_unit > 0 and self.measurement_noise_scale > 0):
            raise ValueError("noise settings must be positive")


# --- compiled filter ----------------------------------------------------------------------------------
@njit(cache=True)
def _predict(x: Array, P: Array, dt: float, q: float) -> None:
    """``x = A x``, ``P = A P A^T + diag(0, q)``; the phase kept in [0, 1]."""
    x[0] = min(max(x[0] + dt * x[1], 0.0), 1.0)
    p01 = P[0, 1] + dt * P[1, 1]
    P[0, 0] = P[0, 0] + dt * (P[0, 1] + P[1, 0]) + dt * dt * P[1, 1]
    P[0, 1] = p01
    P[1, 0] = p01
    P[1, 1] = P[1, 1] + q


@njit(cache=True)
def _update(
    x: Array, P: Array, z: Array, Z: Array, A: Array, W: Array, par: Array, rho: Array, gp: Array,
    vfloor: float, rscale: float, max_rate: float,
    h: Array, H: Array, R: Array, y: Array, S: Array, K: Array, L: Array,
) -> tuple[int, float, float]:  # fmt: skip
    """Seed 003 eq. 2-9 with the channels of ``z`` (6,) that are finite; returns ``(m, maha^2, log det S)``.

    ``gp`` ``(3, 6)`` receives the GPs' mean, mean derivative and variance at the prior phase; ``L`` is
    ``(6, 6)`` scratch. ``y``, ``S``, ``K`` are NaN on the channels left out. Joseph-form covariance.
    """
    phi, rate = x[0], x[1]
    stack_eval(phi, Z, A, W, par, rho, gp[0], gp[1], gp[2])
    for j in range(3):
        h[j] = gp[0, j]
        H[j, 0], H[j, 1] = gp[1, j], 0.0
        R[j, j] = gp[2, j] * rscale
        v = 3 + j
        h[v] = gp[0, v] * rate
        H[v, 0], H[v, 1] = rate * gp[1, v], gp[0, v]
        R[v, v] = (rate * rate * gp[2, v] + vfloor) * rscale
    idx = np.empty(6, np.int64)  # numba keeps these small arrays off the heap when it can
    m = 0
    for i in range(6):
        y[i] = np.nan
        for k in range(6):
            S[i, k] = np.nan
        K[0, i] = K[1, i] = np.nan
        if math.isfinite(z[i]):
            idx[m] = i
            m += 1
    if m == 0:
        return 0, 0.0, 0.0
    PH = np.empty((2, m))  # P H^T
    for a in range(m):
        i = idx[a]
        y[i] = z[i] - h[i]
        PH[0, a] = P[0, 0] * H[i, 0] + P[0, 1] * H[i, 1]
        PH[1, a] = P[1, 0] * H[i, 0] + P[1, 1] * H[i, 1]
    for a in range(m):  # S = H P H^T + R, then its Cholesky factor in L
        for b in range(m):
            s = H[idx[a], 0] * PH[0, b] + H[idx[a], 1] * PH[1, b]
            S[idx[a], idx[b]] = s + (R[idx[a], idx[a]] if a == b else 0.0)
    logdet = 0.0
    for a in range(m):
        for b in range(a + 1):
            s = S[idx[a], idx[b]]
            for k in range(b):
                s -= L[a, k] * L[b, k]
            if a == b:
                if not s > 0.0:
                    return -1, 0.0, 0.0
                L[a, a] = math.sqrt(s)
                logdet += 2.0 * math.log(L[a, a])
            else:
                L[a, b] = s / L[b, b]
    # K^T = S^-1 (P H^T)^T, and S^-1 y, by forward and back substitution
    rhs = np.empty((m, 3))
    for a in range(m):
        rhs[a, 0], rhs[a, 1], rhs[a, 2] = PH[0, a], PH[1, a], y[idx[a]]
    for c in range(3):
        for a in range(m):
            s = rhs[a, c]
            for k in range(a):
                s -= L[a, k] * rhs[k, c]
            rhs[a, c] = s / L[a, a]
    maha2 = 0.0
    for a in range(m):
        maha2 += rhs[a, 2] * rhs[a, 2]
    for c in range(3):
        for a in range(m - 1, -1, -1):
            s = rhs[a, c]
            for k in range(a + 1, m):
                s -= L[k, a] * rhs[k, c]
            rhs[a, c] = s / L[a, a]
    dx0 = dx1 = 0.0
    for a in range(m):
        K[0, idx[a]], K[1, idx[a]] = rhs[a, 0], rhs[a, 1]
        dx0 += rhs[a, 0] * y[idx[a]]
        dx1 += rhs[a, 1] * y[idx[a]]
    # Joseph form: P = (I - K H) P (I - K H)^T + K R K^T
    i00, i01, i10, i11 = 1.0, 0.0, 0.0, 1.0
    for a in range(m):
        i = idx[a]
        i00 -= K[0, i] * H[i, 0]
        i01 -= K[0, i] * H[i, 1]
        i10 -= K[1, i] * H[i, 0]
        i11 -= K[1, i] * H[i, 1]
    t00 = i00 * P[0, 0] + i01 * P[1, 0]
    t01 = i00 * P[0, 1] + i01 * P[1, 1]
    t10 = i10 * P[0, 0] + i11 * P[1, 0]
    t11 = i10 * P[0, 1] + i11 * P[1, 1]
    n00 = t00 * i00 + t01 * i01
    n01 = t00 * i10 + t01 * i11
    n11 = t10 * i10 + t11 * i11
    for a in range(m):
        i = idx[a]
        r = R[i, i]
        n00 += K[0, i] * r * K[0, i]
        n01 += K[0, i] * r * K[1, i]
        n11 += K[1, i] * r * K[1, i]
    P[0, 0], P[0, 1], P[1, 0], P[1, 1] = n00, n01, n01, n11
    x[0] = min(max(x[0] + dx0, 0.0), 1.0)
    x[1] = min(max(x[1] + dx1, 0.0), max_rate)
    return m, maha2, logdet


@njit(cache=True)
def _stance_step(
    x: Array, P: Array, dt: float, q: float, z: Array, Z: Array, A: Array, W: Array, par: Array, rho: Array,
    gp: Array, vfloor: float, rscale: float, max_rate: float,
    h: Array, H: Array, R: Array, y: Array, S: Array, K: Array, L: Array, buf: Array, n: int, t: float,
) -> tuple[int, float, float]:  # fmt: skip
    """One stance sample in one call: :func:`_predict` (``dt`` > 0), :func:`_update`, and ``(t, z)`` into
    row ``n`` of ``buf`` (``n`` < 0: not collected). ``m`` is -2 when the state or covariance is not
    finite afterwards."""
    if dt > 0.0:
        _predict(x, P, dt, q)
    m, maha2, logdet = _update(x, P, z, Z, A, W, par, rho, gp, vfloor, rscale, max_rate, h, H, R, y, S, K, L)
    if n >= 0:
        buf[n, 0] = t
        for i in range(6):
            buf[n, 1 + i] = z[i]
    if not math.isfinite(x[0] + x[1] + P[0, 0] + P[0, 1] + P[1, 1]):
        return -2, 0.0, 0.0
    return m, maha2, logdet


# --- the filter ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Offer:
    """What :meth:`GPEKF.offer` did with a model set: accepted (installed at the next heel strike) or
    refused, and why."""

    version: int
    accepted: bool
    reason: str = ""


@dataclass(frozen=True)
class Installed:
    """A model set the filter installed: at heel strike time ``t`` (NaN: at construction), after
    ``step`` completed stances."""

    version: int
    t: float
    step: int
    models: GPModelSet


class GPEKF:
    """Seed 003's GP-EKF over one stance at a time, with its training data and model versions.

    Streaming use: :meth:`step` per sample. Filter use (filterpy's shape): :meth:`predict`, :meth:`update`.

    Retraining (pure: nothing here fits, waits or logs): every ``retrain_every`` completed stances
    :meth:`take_window` returns a :class:`TrainingWindow` (once; None while frozen); a caller fits it
    (:func:`fit_models`) and hands the result to :meth:`offer`, which checks it (:func:`check_models`) and,
    if it passes, keeps it waiting; the waiting set is installed atomically at the next heel strike (never
    mid-stance). ``frozen`` True refuses offers, offers no windows and installs nothing retrained (a set
    accepted before waits until unfrozen); :meth:`rollback` reinstalls a kept version at the next heel
    strike, also while frozen (it is the operator's choice); :meth:`install_next` installs a given set
    there unchecked (a review replaying a recording). The last
    ``keep_versions`` installs are kept (:attr:`installed`), with their models and windows, so that a review
    can reproduce what ran.

    Attributes:
        x: ``[phi, phidot]``; P: ``(2, 2)``. y: innovation ``(6,)``, S ``(6, 6)``, K ``(2, 6)`` of the last
            update (NaN on channels left out); z_pred, H, R: ``h(x)``, Jacobian, noise at the last prior.
        log_likelihood, mahalanobis: of the last update's innovation.
        models: the installed model set. frozen: see above.
        in_stance: between a heel strike and its toe-off. stance_start: that heel strike's time.
        last_stance: ``T_(n-1)``, the last completed stance's duration (s), of a stance within
            ``max_stance_ratio`` of the one it followed (a stance with a stop in it would reset the next
            to a crawl and arm its toe-off seconds late; two such stances alike in a row are a new pace
            and are taken). reset_rate: ``1 / T_(n-1)`` at this stance's heel strike (the time-based
            estimate's rate).
        steps: completed stances so far.
    """

    def __init__(self, models: GPModelSet, config: GPEKFConfig | None = None):
        self.config = config or GPEKFConfig()
        self.initial = models
        self.frozen = False
        self.x = np.zeros(2)
        self.P = np.zeros((2, 2))
        self.y = np.full(6, np.nan)
        self.S = np.full((6, 6), np.nan)
        self.K = np.full((2, 6), np.nan)
        self.z_pred = np.zeros(6)
        self.H = np.zeros((6, 2))
        self.R = np.zeros((6, 6))
        self._gp = np.zeros((3, 6))
        self._L = np.zeros((6, 6))
        self._buf = np.empty((512, 7))
        self._start()

    def _start(self) -> None:
        c = self.config
        self.models = self.initial
        self._stack = self.initial.stack
        self.x[:] = (0.0, 1.0 / c.initial_stance_s)
        self.P[:] = 0.0
        self.log_likelihood = self.mahalanobis = 0.0
        self.in_stance = False
        self.stance_start = math.nan
        self.last_stance = c.initial_stance_s
        self._odd = math.nan  # a stance too unlike the last to time the next one by
        self.reset_rate = 1.0 / c.initial_stance_s
        self.steps = 0
        self._history: deque[Installed] = deque(
            [Installed(self.initial.version, math.nan, 0, self.initial)], c.keep_versions
        )
        self._waiting: GPModelSet | None = None
        self._rolling_back = False
        self._newest = self.initial.version
        self._window: TrainingWindow | None = None
        self._windows = 0
        self._stances: deque[tuple[int, float, Array]] = deque(maxlen=c.window_steps)
        self._n = 0
        self._knee_peak, self._knee_peak_t = -math.inf, math.nan
        self._at_one: float | None = None
        self._q_dt, self._q = -1.0, 0.0

    def reset(self) -> None:
        """Back to the initial model and state (tuning and ``frozen`` kept)."""
        self._start()

    def restart(self) -> None:
        """Drop the stance under way (after a gap): wait for the next heel strike; models, history and
        ``T_(n-1)`` are kept."""
        self.in_stance = False
        self._n = 0
        self._at_one = None

    # filterpy shape ------------------------------------------------------------------------------------
    def predict(self, dt: float) -> None:
        """Eq. 1 over ``dt`` seconds."""
        if dt != self._q_dt:
            self._q_dt, self._q = dt, self.config.q_phase_rate * dt / self.config.q_time_unit
        _predict(self.x, self.P, dt, self._q)

    def update(self, z: Array | None) -> None:
        """Eq. 2-9 with ``z`` (6,): angles (deg) then velocities (deg/s), NaN missing; None skips."""
        if z is None:
            return
        s, c = self._stack, self.config
        m, maha2, logdet = _update(
            self.x, self.P, z, s.Z, s.A, s.W, s.par, s._rho, self._gp, c.velocity_noise_floor,
            c.measurement_noise_scale, c.max_phase_rate, self.z_pred, self.H, self.R, self.y, self.S, self.K, self._L,
        )  # fmt: skip
        self._likelihood(m, maha2, logdet)

    def _likelihood(self, m: int, maha2: float, logdet: float) -> None:
        if m <= 0:  # nothing measured, or S not positive definite (impossible with positive noise): the prior
            self.mahalanobis, self.log_likelihood = 0.0, 0.0
        else:
            self.mahalanobis = math.sqrt(maha2)
            self.log_likelihood = -0.5 * (maha2 + logdet + m * math.log(2.0 * math.pi))

    @property
    def phase(self) -> float:
        return float(self.x[0])

    @property
    def phase_rate(self) -> float:
        return float(self.x[1])

    # streaming -----------------------------------------------------------------------------------------
    def step(self, t: float, dt: float, z: Array, heel_strike: bool) -> int:
        """One sample at ``t`` (``dt`` after the last): the heel strike (eq. 10) or, in stance, predict and
        update, then toe-off. Returns the bits :data:`HEEL_STRIKE`, :data:`TOE_OFF`, :data:`DIVERGED` of what
        happened."""
        if heel_strike:
            self.heel_strike(t, z)
            return HEEL_STRIKE
        if not self.in_stance:
            return 0
        c, st, n = self.config, self._stack, self._n
        if dt != self._q_dt:
            self._q_dt, self._q = dt, c.q_phase_rate * dt / c.q_time_unit
        if t - self.stance_start > c.max_stance_s:
            n = -1  # too long to be a stance the filter will learn from: not collected
        elif n == self._buf.shape[0]:
            self._buf = np.concatenate([self._buf, np.empty_like(self._buf)])
        m, maha2, logdet = _stance_step(
            self.x, self.P, dt, self._q, z, st.Z, st.A, st.W, st.par, st._rho, self._gp, c.velocity_noise_floor,
            c.measurement_noise_scale, c.max_phase_rate, self.z_pred, self.H, self.R, self.y, self.S, self.K,
            self._L, self._buf, n, t,
        )  # fmt: skip
        self._n += n >= 0
        self._likelihood(m, maha2, logdet)
        event = 0
        if m == -2:  # cannot happen with finite inputs and positive noise; never let it out
            phi = float(self.x[0])
            self.x[:] = (min(max(phi, 0.0), 1.0) if math.isfinite(phi) else 0.0, self.reset_rate)
            self.P[:] = 0.0
            event = DIVERGED
        t_to = self._toe_off(t, z)
        if t_to is None:
            return event
        self._end_stance(t_to)
        return event | TOE_OFF

    def heel_strike(self, t: float, z: Array | None = None) -> None:
        """Install a waiting model set, reset (eq. 10) and start collecting the stance."""
        if self._waiting is not None and (self._rolling_back or not self.frozen):
            self.models, self._waiting, self._rolling_back = self._waiting, None, False
            self._stack = self.models.stack
            self._history.append(Installed(self.models.version, t, self.steps, self.models))
        self.reset_rate = 1.0 / self.last_stance
        self.x[:] = (0.0, self.reset_rate)
        self.P[:] = 0.0
        self.in_stance, self.stance_start, self._n = True, t, 0
        self._knee_peak, self._knee_peak_t, self._at_one = -math.inf, math.nan, None
        if z is not None:
            self._collect(t, z)

    def _collect(self, t: float, z: Array) -> None:
        n = self._n
        if t - self.stance_start > self.config.max_stance_s:
            return  # too long to be a stance the filter will learn from
        if n == self._buf.shape[0]:
            self._buf = np.concatenate([self._buf, np.empty_like(self._buf)])
        row = self._buf[n]
        row[0] = t
        row[1:] = z
        self._n = n + 1

    def _toe_off(self, t: float, z: Array) -> float | None:
        """The toe-off's time if this sample ends the stance (module docstring), else None."""
        c = self.config
        if self.x[0] >= 1.0:
            if self._at_one is None:
                self._at_one = t
            if c.toe_off == "phase":
                return t
            if t - self._at_one >= c.toe_off_overdue * self.last_stance:
                return self._at_one
        if c.toe_off == "knee" and t - self.stance_start >= c.toe_off_earliest * self.last_stance:
            v = float(z[4])
            if v > self._knee_peak:
                self._knee_peak, self._knee_peak_t = v, t
            elif self._knee_peak >= c.toe_off_knee_dps and v <= (1.0 - c.toe_off_drop) * self._knee_peak:
                return self._knee_peak_t
        return None

    def _end_stance(self, t_to: float) -> None:
        c = self.config
        self.in_stance, self._at_one = False, None
        T = t_to - self.stance_start
        if not c.min_stance_s <= T <= c.max_stance_s:
            return  # not a stance to learn from or to time the next one by
        r = c.max_stance_ratio
        if self.last_stance / r <= T <= self.last_stance * r or (self._odd / r <= T <= self._odd * r):
            self.last_stance, self._odd = T, math.nan
        else:
            self._odd = T  # a stop in it, or a new pace: a second one alike will tell
        self.steps += 1
        rows = self._buf[: self._n]
        self._stances.append((self.steps, T, rows[rows[:, 0] <= t_to].copy()))
        if self.steps % c.retrain_every == 0 and len(self._stances) >= 2:
            self._windows += 1
            self._window = self._make_window(self._windows)

    def _make_window(self, index: int) -> TrainingWindow:
        rows = np.concatenate([r for _, _, r in self._stances])
        t0 = np.concatenate([np.full(len(r), r[0, 0]) for _, _, r in self._stances])
        T = np.concatenate([np.full(len(r), T) for _, T, r in self._stances])
        step = np.concatenate([np.full(len(r), k, dtype=np.int64) for k, _, r in self._stances])
        return TrainingWindow(index, rows[:, 0], step, (rows[:, 0] - t0) / T, 1.0 / T, rows[:, 1:4], rows[:, 4:7])

    # retraining ----------------------------------------------------------------------------------------
    @property
    def window_ready(self) -> bool:
        """A training window is there to take (frozen or not)."""
        return self._window is not None

    def take_window(self) -> TrainingWindow | None:
        """The newest training window not yet taken (None: none, or frozen)."""
        w, self._window = self._window, None
        return None if self.frozen else w

    def offer(self, models: GPModelSet) -> Offer:
        """Check ``models`` against the installed set on its window's held-out stance; if it passes it is
        installed at the next heel strike (replacing any set still waiting)."""
        if self.frozen:
            return Offer(models.version, False, "the models are frozen")
        if models.version <= self._newest:
            return Offer(models.version, False, f"version {models.version} is not newer than {self._newest}")
        why = check_models(models, self.models, self.config)
        if why:
            return Offer(models.version, False, why)
        self._waiting, self._newest, self._rolling_back = models, models.version, False
        return Offer(models.version, True)

    def install_next(self, models: GPModelSet) -> None:
        """Install ``models`` at the next heel strike as given: no check, through a freeze, replacing any set
        waiting (a review replaying the installs a recording says ran, at the heel strikes they ran at)."""
        self._waiting, self._rolling_back = models, True
        self._newest = max(self._newest, models.version)

    def rollback(self, version: int) -> str:
        """Reinstall a kept version (or the initial one) at the next heel strike; returns why it cannot (''
        when it will)."""
        kept = {e.version: e.models for e in self._history} | {self.initial.version: self.initial}
        if version in kept:
            self._waiting, self._rolling_back = kept[version], True
            return ""
        return f"version {version} is not kept (kept: {', '.join(str(v) for v in self.kept_versions)})"

    @property
    def installed(self) -> tuple[Installed, ...]:
        """The last ``keep_versions`` installs, oldest first (the current one last)."""
        return tuple(self._history)

    @property
    def kept_versions(self) -> tuple[int, ...]:
        """The versions :meth:`rollback` can reinstall (the initial one always)."""
        return tuple(sorted({self.initial.version, *(e.version for e in self._history)}))

    @property
    def waiting_version(self) -> int | None:
        """The version to be installed at the next heel strike (None: none)."""
        return None if self._waiting is None else self._waiting.version

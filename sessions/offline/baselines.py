"""Library baselines of the registered estimators, for the per-estimator rows of ``gaitscope bench``.

A baseline is what an estimator would be written with a general-purpose filtering library: the same
model, the library's own predict and update, plain vectorised numpy. Two estimators have a natural one,
both on filterpy's ``ExtendedKalmanFilter``:

- ``phase_ekf``: :class:`~gaitscope.estimators.reference.ReferencePhaseEKF`, the filter core only
  (:class:`PhaseEKFCore`): predict and update on the measurement row, with the heel positions already
  high-passed. ``phase_ekf``'s step does more (high-pass, detection, the backup filter, health checks),
  so the cost ratio understates the filter's own speed-up, which the EKF row of the bench measures.
- ``hs_backup``: :class:`ReferenceHeelStrikeBackup`, the whole standalone step, so its outputs, state
  and covariance are compared with gaitscope's in the same run.

The timing-based estimate (``tbe``: a division and a modulo per sample) and the heel-strike detector
(``hs_detector``: threshold tests) are no filter of any library; they have no baseline (:data:`BASELINES`
leaves them out) rather than an invented one.

Like :mod:`gaitscope.estimators.reference`, nothing here is used at run time (the backup's twin could join
``ReferencePhaseEKF`` there).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Final, Protocol

import numpy as np
from filterpy.kalman import ExtendedKalmanFilter
from numpy.typing import NDArray

from gaitscope.estimators.basis import Array
from gaitscope.estimators.gait_model import N_CHANNELS, NoiseModel
from gaitscope.estimators.heel_strike import BackupConfig
from gaitscope.estimators.phase_ekf import EKFConfig, pseudo_from_stride
from gaitscope.estimators.protocol import MAX_GAP_S, elapsed
from gaitscope.estimators.reference import ReferencePhaseEKF
from gaitscope.sessions.formats.replay_io import ReplayInput
from gaitscope.sessions.offline.replay import measurements
from gaitscope.sessions.registry import StackContext

__all__ = ["BASELINES", "Baseline", "PhaseEKFCore", "ReferenceHeelStrikeBackup", "Stepper"]


class Stepper(Protocol):
    """What the bench runs of a baseline: a step per sample, and its state and covariance."""

    @property
    def x(self) -> Array: ...

    @property
    def P(self) -> Array: ...

    def step(self, t: float, z: NDArray[np.float64]) -> NDArray[np.float64]: ...


class PhaseEKFCore:
    """:class:`~gaitscope.estimators.reference.ReferencePhaseEKF` stepped per sample: predict over the time since
    the previous sample (0.01 s before the first), then update with ``z``, the six measurements in the
    EKF's order (heel positions high-passed, NaN where missing). Returns the state ``[p, pdot, lp, r]``."""

    def __init__(self, ctx: StackContext):
        self.ref = ReferencePhaseEKF(ctx.model.coef, ctx.model.noise, ctx.leg_length)
        self._t: float | None = None
        self._first_dt = ctx.sample_period

    @property
    def x(self) -> Array:
        return self.ref.x

    @property
    def P(self) -> Array:
        return self.ref.P

    def step(self, t: float, z: NDArray[np.float64]) -> NDArray[np.float64]:
        dt = self._first_dt if self._t is None else t - self._t
        self._t = t
        self.ref.predict(dt)
        self.ref.update(z)
        return self.ref.x


class ReferenceHeelStrikeBackup:
    """filterpy twin of the standalone :class:`~gaitscope.estimators.heel_strike.HeelStrikeBackup` (``hs_backup``).

    The same model written the direct way: the open-loop phase in plain Python (reset at a heel strike,
    its rate from the last plausible stride period) and a two-state ``ExtendedKalmanFilter`` over
    ``x = [lp, r]`` with ``F = I`` and ``Q = diag(q_rate) dt``, whose measurement and Jacobian are the
    reference phase EKF's (Kronecker regressor, :class:`~gaitscope.estimators.reference.ReferencePhaseEKF`) at
    ``[phase, phase_rate, lp, r]``, columns lp and r, and ``R = Sigma_R(phase)`` on the finite channels.
    An extended filter and not filterpy's linear ``KalmanFilter``: the gait model is nonlinear in lp
    and r, and the backup re-linearises it at every sample as gaitscope's does. filterpy's update is
    Joseph-form, as gaitscope's kernel.

    ``step(t, z)`` takes the stack's ``z`` (heel strike, foot angle and velocity, shank angle and
    velocity) and returns phase, phase rate, stride length (m) and incline (deg).
    """

    name = "hs_backup"

    def __init__(
        self,
        coef: Array,
        noise: NoiseModel,
        leg_length: float,
        ekf_config: EKFConfig | None = None,
        config: BackupConfig | None = None,
        channel_mask: NDArray[np.bool_] | None = None,
        max_gap_s: float = MAX_GAP_S,
    ):
        self.config = config or BackupConfig()
        self._ekf_config = ekf_config or EKFConfig()
        self._model = ReferencePhaseEKF(coef, noise, leg_length, self._ekf_config)  # h, H, scaled Sigma_R
        self._unmodelled = None if channel_mask is None else ~np.asarray(channel_mask, dtype=bool)
        self.leg_length = float(leg_length)
        self.max_gap_s = max_gap_s
        self.kf = ExtendedKalmanFilter(dim_x=2, dim_z=N_CHANNELS)
        self._t: float | None = None
        self._start()

    def _start(self) -> None:
        cfg = self._ekf_config
        self.kf.x = np.array([pseudo_from_stride(cfg.initial_stride_length), cfg.initial_incline])
        self.kf.P = self.config.p0 * np.eye(2)
        self.phase = 0.0
        self.phase_rate = 1.0 / self.config.initial_period
        self._last_hs: float | None = None

    @property
    def x(self) -> Array:
        """``[lp, r]``."""
        return np.asarray(self.kf.x, dtype=np.float64)

    @property
    def P(self) -> Array:
        """``(2, 2)``."""
        return np.asarray(self.kf.P, dtype=np.float64)

    def _full(self, x: Array) -> Array:
        return np.array([self.phase, self.phase_rate, x[0], x[1]])

    def step(self, t: float, z: NDArray[np.float64]) -> NDArray[np.float64]:
        dt, restart = elapsed(self._t, t, self.max_gap_s)
        if restart:
            self._start()
        self._t = t
        cfg = self.config
        if z[0] > 0.5:
            if self._last_hs is not None and cfg.min_period <= t - self._last_hs <= cfg.max_period:
                self.phase_rate = 1.0 / (t - self._last_hs)
            self._last_hs = t
            self.phase = 0.0
        else:
            self.phase = (self.phase + self.phase_rate * dt) % 1.0
        self.kf.Q = np.diag(cfg.q_rate) * dt
        self.kf.predict()
        zz = np.full(N_CHANNELS, np.nan)
        zz[:4] = z[1:5]  # the heel positions are not among the standalone backup's inputs
        if self._unmodelled is not None:
            zz[self._unmodelled] = np.nan
        ok = np.isfinite(zz)
        if ok.any():
            model = self._model
            self.kf.dim_z = int(ok.sum())
            self.kf.update(
                zz[ok],
                lambda x: model.jacobian(self._full(x))[ok][:, 2:],
                lambda x: model.hx(self._full(x))[ok],
                R=model.noise.at(self.phase)[np.ix_(ok, ok)],
            )
        lp, r = (float(v) for v in self.kf.x)
        stride = math.atan(math.pi / 4 * lp) * 4 / math.pi + 2  # seed 000 eq. 15, leg lengths
        return np.array([self.phase, self.phase_rate, self.leg_length * stride, r])


@dataclass(frozen=True)
class Baseline:
    """A registered estimator's library baseline.

    Attributes:
        label: what it is, for the bench's table.
        same_step: True when it computes the estimator's whole step (the bench then compares outputs,
            state and covariance sample by sample); False when it is a part of it (the filter core).
        make: builds it for a session's context.
        inputs: its ``z`` per sample from the trial (``(n, m)``, row k for sample k), None: the
            estimator's own ``z``.
    """

    label: str
    same_step: bool
    make: Callable[[StackContext], Stepper]
    inputs: Callable[[ReplayInput], Array] | None = None


#: Baselines by registered estimator name; an estimator not here has no natural library baseline.
BASELINES: Final[dict[str, Baseline]] = {
    "phase_ekf": Baseline("filterpy EKF, filter only", False, PhaseEKFCore, measurements),
    "hs_backup": Baseline(
        "filterpy EKF, same step",
        True,
        lambda c: ReferenceHeelStrikeBackup(
            c.model.coef, c.model.noise, c.leg_length, channel_mask=c.model.channel_mask
        ),
    ),
}

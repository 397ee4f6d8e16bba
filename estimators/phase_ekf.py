"""Phase EKF over ``[phase, phase rate, pseudo stride length, incline]`` (seed 000 section II-C).

State ``x = [p, pdot, lp, r]``: phase in [0, 1), phase rate (1/s), pseudo stride length ``lp`` (any
real; the stride length in leg lengths is ``l = (4/pi) atan(pi lp / 4) + 2``, eq. 15, always in
(0, 4)) and incline r (deg). Measurements ``z`` (6,): foot angle (deg), foot angular velocity (deg/s),
shank angle, shank angular velocity, high-passed heel forward and heel up positions (m); a NaN entry
is a missing sensor and that channel is left out of the update (measurement subsets, II-C3).

Interface as filterpy's ``ExtendedKalmanFilter``: :meth:`PhaseEKF.predict`, :meth:`PhaseEKF.update`
(``z=None`` skips), attributes ``x``, ``P``, ``y``, ``S``, ``K``, ``log_likelihood``, ``mahalanobis``.

Choices where the paper and the authors' code differ (``shared/reference/estimators.md``):

- process noise ``Q = diag(0, s_pdot^2, s_lp^2, s_r^2) * dt / q_time_unit``. The code uses
  ``q_time_unit = 0.01`` s, the text ``1`` s (a factor 100 apart); defaults follow the code, whose
  tuning the reported simulation numbers come from.
- covariance update in Joseph form (as filterpy), algebraically equal to the paper's ``(I - KH) P``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from gaitscope.estimators import _kernels
from gaitscope.estimators.basis import Array
from gaitscope.estimators.gait_model import N_CHANNELS, N_OUTPUTS, NoiseModel

#: Process-noise standard deviations (pdot, lp, r) for simulation and treadmill (seed 000 II-C5).
Q_STD_TREADMILL = (6e-4, 9e-4, 6e-3)
#: Process-noise standard deviations for the outdoor trials.
Q_STD_OUTDOOR = (1e-3, 2e-3, 5e-2)
#: Variance used to freeze a state in the no-task ablation (paper H2).
FROZEN_VARIANCE = 1e-20


def pseudo_from_stride(l_norm: float) -> float:
    """Inverse of eq. 15: the ``lp`` with ``(4/pi) atan(pi lp / 4) + 2 = l_norm``, for l_norm in (0, 4)."""
    if not 0.0 < l_norm < 4.0:
        raise ValueError(f"normalised stride length must be in (0, 4), got {l_norm}")
    return 4.0 / math.pi * math.tan(math.pi / 4.0 * (l_norm - 2.0))


def stride_from_pseudo(lp: float) -> float:
    """Eq. 15: stride length in leg lengths from the pseudo stride length."""
    return _kernels.stride_from_pseudo(lp)[0]


@dataclass(frozen=True)
class EKFConfig:
    """Tuning of :class:`PhaseEKF`; defaults are seed 000's simulation/treadmill values.

    Attributes:
        q_std: process-noise standard deviations of (pdot, lp, r) per ``q_time_unit``.
        q_time_unit: the time over which ``q_std`` accrues (s); see the module docstring.
        p0: initial covariance ``p0 * I``.
        initial_phase_rate: 1/s.
        initial_stride_length: in leg lengths (paper: 1.3).
        initial_incline: deg.
        measurement_noise_scale: multiplies ``Sigma_R(p)``; 1 is the paper.
        process_noise_scale: multiplies ``Q``; 1 is the paper.
        no_task: freeze lp and r at their initial values (the paper's no-task ablation, H2).
    """

    q_std: tuple[float, float, float] = Q_STD_TREADMILL
    q_time_unit: float = 0.01
    p0: float = 1e-3
    initial_phase_rate: float = 1.0
    initial_stride_length: float = 1.3
    initial_incline: float = 0.0
    measurement_noise_scale: float = 1.0
    process_noise_scale: float = 1.0
    no_task: bool = False

    def initial_state(self) -> Array:
        return np.array(
            [
                0.0,
                self.initial_phase_rate,
                pseudo_from_stride(self.initial_stride_length),
                self.initial_incline,
            ]
        )

    def initial_covariance(self) -> Array:
        P = self.p0 * np.eye(4)
        if self.no_task:
            P[2, 2] = P[3, 3] = FROZEN_VARIANCE
        return P

    def q_diag(self, dt: float, out: Array | None = None) -> Array:
        """The process noise's diagonal ``(4,)`` over ``dt`` seconds, into ``out`` when given (in Python
        floats: the filter recomputes it whenever ``dt`` changes, which jitters from sample to sample)."""
        q = np.zeros(4) if out is None else out
        c = dt / self.q_time_unit
        q[0] = 0.0
        for i in range(3):
            q[i + 1] = self.q_std[i] * self.q_std[i] * c * self.process_noise_scale
        if self.no_task:
            q[2] = q[3] = FROZEN_VARIANCE
        return q


class PhaseEKF:
    """Seed 000's phase EKF.

    Args:
        coef: gait-model coefficients ``(4, 2, 2, 2N+1)`` (:mod:`gaitscope.estimators.gait_model`).
        noise: heteroscedastic measurement noise ``Sigma_R(p)``.
        leg_length: the user's leg length (m); scales stride length and heel positions.
        config: tuning.

    Attributes:
        x: state ``(4,)``; P: covariance ``(4, 4)``.
        y: innovation ``(6,)`` of the last update (NaN on channels not measured); S: ``(6, 6)``;
        K: gain ``(4, 6)``; z_pred: ``h(x)`` at the last prior ``(6,)``; H: Jacobian ``(6, 4)``.
        log_likelihood, mahalanobis: of the last update's innovation.
    """

    def __init__(self, coef: Array, noise: NoiseModel, leg_length: float, config: EKFConfig | None = None):
        if coef.ndim != 4 or coef.shape[:3] != (N_OUTPUTS, 2, 2):
            raise ValueError(f"coef must have shape (4, 2, 2, K), got {coef.shape}")
        if not leg_length > 0:
            raise ValueError(f"leg_length must be positive, got {leg_length}")
        self.config = config or EKFConfig()
        self.coef = np.ascontiguousarray(coef, dtype=np.float64)
        self.leg_length = float(leg_length)
        self._noise = noise
        self._bins = np.ascontiguousarray(noise.bins * self.config.measurement_noise_scale)
        # every array and number of a step in one buffer (_kernels.EKF_*), the attributes views of it
        self._buf = buf = np.zeros(_kernels.EKF_SIZE)
        self.x = buf[_kernels.EKF_X : _kernels.EKF_X + 4]
        self.P = buf[_kernels.EKF_P : _kernels.EKF_P + 16].reshape(4, 4)
        self.y = buf[_kernels.EKF_Y : _kernels.EKF_Y + N_CHANNELS]
        self.S = buf[_kernels.EKF_S : _kernels.EKF_S + N_CHANNELS * N_CHANNELS].reshape(N_CHANNELS, N_CHANNELS)
        self.K = buf[_kernels.EKF_K : _kernels.EKF_K + 4 * N_CHANNELS].reshape(4, N_CHANNELS)
        self.z_pred = buf[_kernels.EKF_ZPRED : _kernels.EKF_ZPRED + N_CHANNELS]
        self.H = buf[_kernels.EKF_H : _kernels.EKF_H + N_CHANNELS * 4].reshape(N_CHANNELS, 4)
        self.R = buf[_kernels.EKF_R : _kernels.EKF_R + N_CHANNELS * N_CHANNELS].reshape(N_CHANNELS, N_CHANNELS)
        self._terms = buf[_kernels.EKF_TERMS : _kernels.EKF_TERMS + N_OUTPUTS * 7].reshape(N_OUTPUTS, 7)
        self.x[:] = self.config.initial_state()
        self.P[:] = self.config.initial_covariance()
        self.y[:] = np.nan
        self.S[:] = np.nan
        self.K[:] = np.nan
        buf[_kernels.EKF_LEG] = self.leg_length
        buf[_kernels.EKF_LOG2PI] = math.log(2.0 * math.pi)
        self._set_q()

    def _set_q(self) -> None:
        """The process noise's constants into the buffer (``EKFConfig.q_diag`` makes Q from them)."""
        cfg, buf = self.config, self._buf
        for i in range(3):
            buf[_kernels.EKF_QVAR + i] = cfg.q_std[i] * cfg.q_std[i]
        buf[_kernels.EKF_QUNIT] = cfg.q_time_unit
        buf[_kernels.EKF_QSCALE] = cfg.process_noise_scale
        buf[_kernels.EKF_NOTASK] = 1.0 if cfg.no_task else 0.0

    @property
    def log_likelihood(self) -> float:
        """Of the last update's innovation (0 before the first, or with no channel)."""
        return float(self._buf[_kernels.EKF_LL])

    @log_likelihood.setter
    def log_likelihood(self, value: float) -> None:
        self._buf[_kernels.EKF_LL] = value

    @property
    def mahalanobis(self) -> float:
        """``sqrt(y^T S^-1 y)`` of the last update's innovation."""
        return float(self._buf[_kernels.EKF_MAHA])

    @mahalanobis.setter
    def mahalanobis(self, value: float) -> None:
        self._buf[_kernels.EKF_MAHA] = value

    def predict(self, dt: float) -> None:
        """Advance by ``dt`` seconds (eq. 13-14); phase wrapped into [0, 1)."""
        _kernels.ekf_predict(self._buf, dt)

    def update(self, z: Array | None) -> None:
        """Correct with measurement ``z`` (6,), NaN for missing channels; ``None`` skips."""
        if z is None:
            return
        _kernels.ekf_update_buffer(self.coef, self._bins, self._buf, z)

    def retune(self, measurement_noise_scale: float, process_noise_scale: float) -> None:
        """Change the noise scales from the next step on (a clinician's tuning); the state is kept."""
        if not (measurement_noise_scale > 0 and process_noise_scale > 0):
            raise ValueError("noise scales must be positive")
        self.config = replace(
            self.config,
            measurement_noise_scale=measurement_noise_scale,
            process_noise_scale=process_noise_scale,
        )
        self._bins = np.ascontiguousarray(self._noise.bins * measurement_noise_scale)
        self._set_q()

    def reset(self, x: Array, P: Array) -> None:
        """Overwrite state and covariance (the heel-strike backup's reset, II-D)."""
        self.x[:] = x
        self.x[0] %= 1.0
        self.P[:] = P

    @property
    def phase(self) -> float:
        return float(self.x[0])

    @property
    def phase_rate(self) -> float:
        return float(self.x[1])

    @property
    def stride_length_norm(self) -> float:
        """Stride length in leg lengths."""
        return stride_from_pseudo(float(self.x[2]))

    @property
    def stride_length(self) -> float:
        """Stride length in metres."""
        return self.leg_length * self.stride_length_norm

    @property
    def incline(self) -> float:
        """Incline in degrees."""
        return float(self.x[3])

"""Heel-strike backup filter (seed 000 section II-D) and heel-strike detection.

The backup runs beside the main EKF. Its phase runs open loop from the last heel strike at the rate
of the last stride; a two-state EKF over ``[lp, r]`` uses that phase to track stride length and
incline. Both filters accumulate ``SSE += y^T Rbar^-1 y`` (``y`` the innovation at the prior, ``Rbar``
the phase average of ``Sigma_R``). At each heel strike, if ``SSE_EKF - SSE_HP`` exceeds a margin
(1.2e3 in the authors' code) the main EKF is overwritten with the backup's estimate and
``P = 1e-3 I``; both sums then restart. Order per sample: EKF predict, EKF update, backup, read.

Detection (hardware, section II-E): all of ``0 < foot angle <= 30 deg``, foot angular velocity
< 0, mean absolute heel acceleration over the last 10 samples >= 10 m/s^2, and more than 0.4 s since
the last heel strike. Gaitscope's detector applies the same angle, velocity and refractory tests at
the sample where the foot velocity turns negative (the foot angle's late-swing peak, which is where
the heel lands), and the acceleration test only when heel positions are given and
``accel_threshold`` is set: high-passed positions carry no gravity and differentiating them twice is
noisy, so by default it is off.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from estimators import _kernels
from estimators.basis import Array
from estimators.gait_model import N_CHANNELS, N_OUTPUTS, NoiseModel
from estimators.phase_ekf import PhaseEKF, pseudo_from_stride


@dataclass(frozen=True)
class BackupConfig:
    """Tuning of :class:`HeelStrikeBackup` (defaults: the authors' code).

    Attributes:
        p0: initial covariance of [lp, r].
        q_rate: process noise of (lp, r) per second (``P += diag(q) dt``).
        sse_margin: reset when ``SSE_EKF - SSE_HP`` exceeds this at a heel strike.
        reset_p: the main EKF's covariance after a reset, ``reset_p * I``.
        initial_period: stride period (s) assumed before two heel strikes are seen.
        min_period, max_period: a measured period outside these is ignored (missed or double events).
    """

    p0: float = 1e-3
    q_rate: tuple[float, float] = (1e-4, 5e-3)
    sse_margin: float = 1.2e3
    reset_p: float = 1e-3
    initial_period: float = 1.0
    min_period: float = 0.4
    max_period: float = 4.0


class HeelStrikeBackup:
    """Seed 000's heel-strike backup filter over ``[lp, r]`` with open-loop phase.

    Attributes:
        x: ``[lp, r]``; P: ``(2, 2)``; phase, phase_rate: the open-loop phase; resets: count.
    """

    def __init__(self, ekf: PhaseEKF, noise: NoiseModel, config: BackupConfig | None = None):
        self.config = config or BackupConfig()
        self.ekf = ekf
        self.x = np.array([pseudo_from_stride(ekf.config.initial_stride_length), ekf.config.initial_incline])
        self.P = self.config.p0 * np.eye(2)
        self.phase = 0.0
        self.phase_rate = 1.0 / self.config.initial_period
        self.sse_ekf = 0.0
        self.sse_hp = 0.0
        self.resets = 0
        self._noise = noise
        self._rbar = np.ascontiguousarray(noise.mean() * ekf.config.measurement_noise_scale)
        self._last_hs: float | None = None
        self._terms = np.zeros((N_OUTPUTS, 7))
        self._x4 = np.zeros(4)
        self._h = np.zeros(N_CHANNELS)
        self._H = np.zeros((N_CHANNELS, 4))
        self._y = np.zeros(N_CHANNELS)
        self._S = np.zeros((N_CHANNELS, N_CHANNELS))
        self._K = np.zeros((2, N_CHANNELS))

    def retune(self) -> None:
        """Follow the main EKF's measurement-noise scale (after :meth:`PhaseEKF.retune`)."""
        self._rbar = np.ascontiguousarray(self._noise.mean() * self.ekf.config.measurement_noise_scale)

    def step(self, t: float, dt: float, z: Array | None, heel_strike: bool) -> bool:
        """Run after the main EKF's update for the sample at time ``t``; True if it reset the EKF."""
        cfg = self.config
        if heel_strike:
            if self._last_hs is not None:
                period = t - self._last_hs
                if cfg.min_period <= period <= cfg.max_period:
                    self.phase_rate = 1.0 / period
            self._last_hs = t
            self.phase = 0.0
        else:
            self.phase = (self.phase + self.phase_rate * dt) % 1.0
        self.P[0, 0] += cfg.q_rate[0] * dt
        self.P[1, 1] += cfg.q_rate[1] * dt
        if z is not None:
            self._x4[:] = (self.phase, self.phase_rate, self.x[0], self.x[1])
            _kernels.measurement(self.ekf.coef, self._x4, self.ekf.leg_length, self._terms, self._h, self._H)
            H2 = np.ascontiguousarray(self._H[:, 2:4])
            _kernels.update(self.x, self.P, z, self._h, H2, self.ekf.R, self._y, self._S, self._K, False)
            self.sse_hp += _kernels.weighted_sse(self._y, self._rbar)
            self.sse_ekf += _kernels.weighted_sse(self.ekf.y, self._rbar)
        reset = False
        if heel_strike:
            if self.sse_ekf - self.sse_hp > cfg.sse_margin:
                self.ekf.reset(np.array([self.phase, self.phase_rate, self.x[0], self.x[1]]), cfg.reset_p * np.eye(4))
                self.resets += 1
                reset = True
            self.sse_ekf = self.sse_hp = 0.0
        return reset


@dataclass(frozen=True)
class DetectorConfig:
    """Heel-strike detection thresholds (seed 000 II-E).

    Attributes:
        max_foot_angle_deg: the foot angle must lie in (0, this].
        refractory_s: minimum time between heel strikes.
        accel_threshold: mean |heel acceleration| (m/s^2) over ``accel_window`` samples, or None to skip.
        accel_window: samples averaged for the acceleration test.
    """

    max_foot_angle_deg: float = 30.0
    refractory_s: float = 0.4
    accel_threshold: float | None = None
    accel_window: int = 10


class HeelStrikeDetector:
    """Streaming heel-strike detector from foot angle and angular velocity (and heel positions)."""

    def __init__(self, config: DetectorConfig | None = None):
        self.config = config or DetectorConfig()
        self._last_hs = -math.inf
        self._prev_vel = math.nan
        self._heel: list[Array] = []
        self._acc: list[float] = []

    def step(self, t: float, dt: float, foot_angle: float, foot_vel: float, heel: Array | None = None) -> bool:
        """Feed one sample; True when it is a heel strike."""
        cfg = self.config
        if cfg.accel_threshold is not None and heel is not None and dt > 0:
            self._heel.append(np.asarray(heel, dtype=np.float64))
            if len(self._heel) > 3:
                self._heel.pop(0)
            if len(self._heel) == 3:
                a = (self._heel[2] - 2 * self._heel[1] + self._heel[0]) / (dt * dt)
                self._acc.append(float(np.linalg.norm(a)))
                if len(self._acc) > cfg.accel_window:
                    self._acc.pop(0)
        turned = self._prev_vel >= 0.0 and foot_vel < 0.0
        self._prev_vel = foot_vel
        if not turned or not 0.0 < foot_angle <= cfg.max_foot_angle_deg:
            return False
        if t - self._last_hs <= cfg.refractory_s:
            return False
        if cfg.accel_threshold is not None:
            if not self._acc or float(np.mean(self._acc)) < cfg.accel_threshold:
                return False
        self._last_hs = t
        return True


class TimingBasedEstimator:
    """Timing-based phase estimate, the paper's TBE baseline (seed 000 III-B).

    ``phase = (t - t_lastHS) / T_prev mod 1`` with ``T_prev`` the duration of the previous stride only,
    initialised to ``initial_period`` (1 s in the paper). Same interface as the Kalman filters:
    :meth:`predict` advances time, :meth:`update` takes ``z = [1]`` on a heel strike (``None`` skips).

    Attributes:
        x: ``[phase, phase_rate]``.
    """

    def __init__(self, initial_period: float = 1.0, min_period: float = 0.4, max_period: float = 4.0):
        self.period = initial_period
        self.min_period, self.max_period = min_period, max_period
        self.t = 0.0
        self._last_hs = 0.0
        self._seen_hs = False
        self.x = np.array([0.0, 1.0 / initial_period])

    def predict(self, dt: float) -> None:
        self.t += dt
        self._refresh()

    def update(self, z: Array | None) -> None:
        if z is None or not z[0] > 0.5:
            return
        if self._seen_hs:
            period = self.t - self._last_hs
            if self.min_period <= period <= self.max_period:
                self.period = period
        self._seen_hs = True
        self._last_hs = self.t
        self._refresh()

    def _refresh(self) -> None:
        self.x[0] = ((self.t - self._last_hs) / self.period) % 1.0
        self.x[1] = 1.0 / self.period

    @property
    def phase(self) -> float:
        return float(self.x[0])

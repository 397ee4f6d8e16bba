"""The seed-000 estimator stack as one streaming object: what replay and (later) the server run.

Per sample: heel positions through the high-pass filter, heel strike given or detected, main EKF
predict and update, heel-strike backup, timing-based baseline, and the torque command. Pure numpy:
no I/O, no clocks; the caller passes time stamps.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from estimators.basis import Array
from estimators.gait_model import N_CHANNELS, NoiseModel
from estimators.heel_strike import (
    BackupConfig,
    DetectorConfig,
    HeelStrikeBackup,
    HeelStrikeDetector,
    TimingBasedEstimator,
)
from estimators.highpass import HighPassFilter
from estimators.phase_ekf import EKFConfig, PhaseEKF
from estimators.torque import TorqueProfile

FOOT_ANGLE, FOOT_VEL, SHANK_ANGLE, SHANK_VEL, HEEL_FORWARD, HEEL_UP = range(N_CHANNELS)


@dataclass(frozen=True)
class TrainedModel:
    """Everything fitted from training data: gait model, noise model and torque profile.

    Attributes:
        coef: gait-model coefficients ``(4, 2, 2, 2N+1)``.
        noise: ``Sigma_R(p)``.
        torque: the torque profile.
        outputs: which of foot, shank, heel forward and heel up the training data held; channels of
            an output not trained are ignored at run time (a LocoHub table without heel positions).
    """

    coef: Array
    noise: NoiseModel
    torque: TorqueProfile
    outputs: tuple[bool, bool, bool, bool] = (True, True, True, True)

    @property
    def channel_mask(self) -> NDArray[np.bool_]:
        """``(6,)`` True for the measurement channels the model can predict (from ``outputs``)."""
        foot, shank, fwd, up = self.outputs
        return np.array([foot, foot, shank, shank, fwd, up])


@dataclass(frozen=True)
class PipelineConfig:
    """Settings of one estimation pipeline.

    Attributes:
        leg_length: m.
        body_mass_kg: scales the torque profile (N m/kg) to N m.
        torque_gain: multiplies the profile's scale (1 = the paper's 1/5 of the biological moment).
        max_torque: hard bound on the command (N m); the command is always in [0, max_torque].
        use_backup: run the heel-strike backup filter.
        ekf, backup, detector: their own tuning.
    """

    leg_length: float = 0.88
    body_mass_kg: float = 75.0
    torque_gain: float = 1.0
    max_torque: float = 40.0
    use_backup: bool = True
    ekf: EKFConfig = field(default_factory=EKFConfig)
    backup: BackupConfig = field(default_factory=BackupConfig)
    detector: DetectorConfig = field(default_factory=DetectorConfig)


@dataclass(frozen=True)
class GaitEstimate:
    """Output of one pipeline step."""

    phase: float
    phase_rate: float
    stride_length_m: float
    incline_deg: float
    torque_Nm: float
    heel_strike: bool
    tbe_phase: float
    backup_reset: bool


class GaitStatePipeline:
    """Streaming seed-000 estimator.

    Args:
        model: the trained models.
        config: settings.
        sample_period: nominal sample period (s) for the heel high-pass filter's discretisation.
    """

    def __init__(self, model: TrainedModel, config: PipelineConfig | None = None, sample_period: float = 0.01):
        self.model = model
        self.config = config or PipelineConfig()
        cfg = self.config
        if not 0 <= cfg.max_torque <= 200:
            raise ValueError(f"max_torque must be within [0, 200] N m, got {cfg.max_torque}")
        self.ekf = PhaseEKF(model.coef, model.noise, cfg.leg_length, cfg.ekf)
        self.backup = HeelStrikeBackup(self.ekf, model.noise, cfg.backup) if cfg.use_backup else None
        self.tbe = TimingBasedEstimator()
        self.detector = HeelStrikeDetector(cfg.detector)
        self.highpass = HighPassFilter(sample_period)
        self._t: float | None = None
        self._z = np.full(N_CHANNELS, np.nan)
        self._unmodelled = ~model.channel_mask
        self._hs = np.ones(1)

    def retune(
        self,
        *,
        torque_gain: float | None = None,
        max_torque: float | None = None,
        measurement_noise_scale: float | None = None,
        process_noise_scale: float | None = None,
    ) -> None:
        """Change assistance or estimator tuning from the next :meth:`step` on; ``None`` keeps a value."""
        cfg = self.config
        gain = cfg.torque_gain if torque_gain is None else torque_gain
        bound = cfg.max_torque if max_torque is None else max_torque
        if not 0 <= bound <= 200 or not gain >= 0:
            raise ValueError(f"torque gain {gain} and bound {bound} N m must be >= 0 and <= 200 N m")
        self.config = replace(cfg, torque_gain=gain, max_torque=bound)
        if measurement_noise_scale is not None or process_noise_scale is not None:
            ekf_cfg = self.ekf.config
            self.ekf.retune(
                ekf_cfg.measurement_noise_scale if measurement_noise_scale is None else measurement_noise_scale,
                ekf_cfg.process_noise_scale if process_noise_scale is None else process_noise_scale,
            )
            if self.backup is not None:
                self.backup.retune()

    @property
    def predicted(self) -> Array:
        """``h(x)`` at the last prior: model foot angle, foot velocity, shank angle, ... (6,)."""
        return self.ekf.z_pred

    def step(self, t: float, raw: Array, heel_strike: bool | None = None, heel_filtered: bool = False) -> GaitEstimate:
        """Process one sample.

        Args:
            t: time stamp (s), strictly increasing.
            raw: ``(6,)`` foot angle (deg), foot velocity (deg/s), shank angle, shank velocity, heel
                forward and heel up (m, raw unless ``heel_filtered``); NaN where a sensor is missing.
            heel_strike: True/False if known; None to detect it from the foot signals.
            heel_filtered: the heel positions were already high-passed (batch replay does this).
        """
        dt = 0.0 if self._t is None else t - self._t
        if self._t is not None and not dt > 0:
            raise ValueError(f"time must increase: {t} after {self._t}")
        self._t = t
        z = self._z
        z[:] = raw
        heel = z[HEEL_FORWARD : HEEL_UP + 1]
        if not heel_filtered and np.all(np.isfinite(heel)):
            z[HEEL_FORWARD : HEEL_UP + 1] = self.highpass.step(heel)
        z[self._unmodelled] = np.nan
        if heel_strike is None:
            heel_strike = bool(
                np.isfinite(z[FOOT_ANGLE])
                and np.isfinite(z[FOOT_VEL])
                and self.detector.step(t, dt, float(z[FOOT_ANGLE]), float(z[FOOT_VEL]))
            )
        if dt > 0:
            self.ekf.predict(dt)
            self.tbe.predict(dt)
        self.ekf.update(z)
        reset = self.backup.step(t, dt, z, heel_strike) if self.backup is not None else False
        if heel_strike:
            self.tbe.update(self._hs)
        ekf = self.ekf
        l_norm = ekf.stride_length_norm
        cfg = self.config
        torque = self.model.torque.torque_at(
            ekf.phase, l_norm, ekf.incline, cfg.body_mass_kg * cfg.torque_gain, cfg.max_torque
        )
        return GaitEstimate(
            phase=ekf.phase,
            phase_rate=ekf.phase_rate,
            stride_length_m=l_norm * cfg.leg_length,
            incline_deg=ekf.incline,
            torque_Nm=torque,
            heel_strike=heel_strike,
            tbe_phase=self.tbe.phase,
            backup_reset=reset,
        )

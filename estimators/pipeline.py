"""The seed-000 estimator stack as one streaming object: what replay and the server run.

Per sample: implausible sensor values screened out, heel positions through the high-pass filter, heel
strike given or detected, main EKF predict and update, heel-strike backup, timing-based baseline, a
health check of the filter, and the torque command. Pure numpy: no I/O, no clocks; the caller passes
time stamps.

Safety (none of this is in the paper, which assumes clean data; each bound is a
:class:`PipelineConfig` parameter):

- a channel value outside :data:`CHANNEL_LIMITS` (or non-finite) is treated as missing for that
  sample and counted in :attr:`GaitStatePipeline.implausible`;
- a gap between samples longer than ``max_gap_s`` restarts the filters (the walker may have stopped,
  and one predict over the gap would blow the covariance up); the estimate says ``fault="gap"``;
- a filter whose state or covariance is non-finite or outside :class:`HealthLimits` is reset from the
  heel-strike backup, else from the timing-based estimate, else from its initial state
  (``fault="diverged"``); the torque of that sample is 0;
- the torque is always a finite number in ``[0, max_torque]``: anything else becomes 0 with
  ``fault="torque"``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from gaitscope.estimators import _batch, _kernels, channels
from gaitscope.estimators.basis import Array
from gaitscope.estimators.fingerprint import FingerprintMap
from gaitscope.estimators.gait_model import N_CHANNELS, Z_FOOT_ANGLE, Z_FOOT_VEL, Z_HEEL_FORWARD, Z_HEEL_UP, NoiseModel
from gaitscope.estimators.heel_strike import (
    BackupConfig,
    DetectorConfig,
    HeelStrikeBackup,
    HeelStrikeDetector,
    TimingBasedEstimator,
)
from gaitscope.estimators.highpass import HighPassFilter
from gaitscope.estimators.phase_ekf import EKFConfig, PhaseEKF
from gaitscope.estimators.protocol import SENSOR_CHANNELS
from gaitscope.estimators.torque import TorqueProfile

#: Physically plausible range of each measurement channel, in channel order (:data:`SENSOR_CHANNELS`), from
#: the channel table (:mod:`gaitscope.estimators.channels`, where the ranges are explained): segment angles
#: within +/-180 deg, angular velocities within +/-4000 deg/s and raw heel positions within +/-3 m of the hip.
CHANNEL_LIMITS: tuple[tuple[float, float], ...] = channels.limits(SENSOR_CHANNELS)


@dataclass(frozen=True)
class HealthLimits:
    """When the phase EKF counts as diverged (beyond non-finite values), and is reset.

    Attributes:
        min_phase_rate, max_phase_rate: 1/s; walking spans about 0.3-1.5 strides/s, running up to 1.8.
        max_abs_incline: deg; ramps steeper than this are not walked with a device.
        max_variance: largest allowed diagonal entry of ``P`` (the initial one is 1e-3).
    """

    min_phase_rate: float = -0.5
    max_phase_rate: float = 4.0
    max_abs_incline: float = 45.0
    max_variance: float = 1e3


@dataclass(frozen=True)
class TrainedModel:
    """Everything fitted from training data: gait model, noise model and torque profile.

    Attributes:
        coef: gait-model coefficients ``(4, 2, 2, 2N+1)``.
        noise: ``Sigma_R(p)``.
        torque: the torque profile.
        outputs: which of foot, shank, heel forward and heel up the training data held; channels of
            an output not trained are ignored at run time (a LocoHub table without heel positions).
        fingerprints: seed 004's personalization map of the thigh angle (None: the training data had
            no thigh angle), for the fingerprint estimators.
    """

    coef: Array
    noise: NoiseModel
    torque: TorqueProfile
    outputs: tuple[bool, bool, bool, bool] = (True, True, True, True)
    fingerprints: FingerprintMap | None = None

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
        channel_limits: plausible range per measurement channel; values outside are missing.
        max_gap_s: a longer gap between two samples restarts the filters.
        health: when the EKF counts as diverged.
    """

    leg_length: float = 0.88
    body_mass_kg: float = 75.0
    torque_gain: float = 1.0
    max_torque: float = 40.0
    use_backup: bool = True
    ekf: EKFConfig = field(default_factory=EKFConfig)
    backup: BackupConfig = field(default_factory=BackupConfig)
    detector: DetectorConfig = field(default_factory=DetectorConfig)
    channel_limits: tuple[tuple[float, float], ...] = CHANNEL_LIMITS
    max_gap_s: float = 1.0
    health: HealthLimits = field(default_factory=HealthLimits)


@dataclass(frozen=True)
class GaitEstimate:
    """Output of one pipeline step.

    ``fault`` is empty normally; else why the filters were restarted or reset at this sample
    (``"gap"``, ``"diverged"``) or why the torque was forced to 0 (``"torque"``).
    """

    phase: float
    phase_rate: float
    stride_length_m: float
    incline_deg: float
    torque_Nm: float
    heel_strike: bool
    tbe_phase: float
    backup_reset: bool
    fault: str = ""
    implausible: int = 0


def _estimate(fields: dict[str, object]) -> GaitEstimate:
    """``GaitEstimate(**fields)`` (every field given), made without the frozen dataclass's ``__init__``, which
    sets each field through ``object.__setattr__``: a third of :meth:`GaitStatePipeline.step`'s Python time.
    The same object (fields, equality, hash); ``tests/estimators/test_pipeline.py`` checks every field is set."""
    estimate = object.__new__(GaitEstimate)
    estimate.__dict__.update(fields)
    return estimate


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
        if not (math.isfinite(sample_period) and sample_period > 0):
            raise ValueError(f"sample_period must be a positive number of seconds, got {sample_period}")
        if len(cfg.channel_limits) != N_CHANNELS:
            raise ValueError(f"channel_limits needs {N_CHANNELS} (low, high) pairs, got {len(cfg.channel_limits)}")
        self._sample_period = sample_period
        self._lo = np.array([lo for lo, _ in cfg.channel_limits])
        self._hi = np.array([hi for _, hi in cfg.channel_limits])
        self._t: float | None = None
        self._z = np.full(N_CHANNELS, np.nan)
        self._heel = self._z[Z_HEEL_FORWARD : Z_HEEL_UP + 1]  # a view: the high-pass filters it in place
        self._unmodelled = ~model.channel_mask
        self._any_unmodelled = bool(self._unmodelled.any())
        self._hs = np.ones(1)
        #: Channel values refused as implausible since the start.
        self.implausible = 0
        #: Times the filters were restarted after a gap or reset after diverging.
        self.restarts = 0
        self.resets = 0
        self._heel_settle = 0.0
        self._heel_masked_until = -math.inf
        self._start_filters()

    def _start_filters(self) -> None:
        """(Re)create every filter in its initial state, keeping the tuning."""
        cfg = self.config
        self.ekf = PhaseEKF(self.model.coef, self.model.noise, cfg.leg_length, cfg.ekf)
        self.backup = HeelStrikeBackup(self.ekf, self.model.noise, cfg.backup) if cfg.use_backup else None
        self.tbe = TimingBasedEstimator()
        self.detector = HeelStrikeDetector(cfg.detector)
        self.highpass = HighPassFilter(self._sample_period)

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
            self.config = replace(self.config, ekf=self.ekf.config)  # a restart keeps the tuning
            if self.backup is not None:
                self.backup.retune()

    @property
    def predicted(self) -> Array:
        """``h(x)`` at the last prior: model foot angle, foot velocity, shank angle, ... (6,)."""
        return self.ekf.z_pred

    def step(
        self,
        t: float,
        raw: Array,
        heel_strike: bool | None = None,
        heel_filtered: bool = False,
        command: bool = True,
    ) -> GaitEstimate:
        """Process one sample.

        Args:
            t: time stamp (s), strictly increasing.
            raw: ``(6,)`` foot angle (deg), foot velocity (deg/s), shank angle, shank velocity, heel
                forward and heel up (m, raw unless ``heel_filtered``); NaN where a sensor is missing.
            heel_strike: True/False if known; None to detect it from the foot signals.
            heel_filtered: the heel positions were already high-passed (batch replay does this).
            command: compute the torque command; False (a session's stack, which commands the torque
                itself): ``torque_Nm`` is 0 and ``fault`` never ``"torque"``, everything else the same.
        """
        if not math.isfinite(t):
            raise ValueError(f"time must be finite, got {t}")
        dt = 0.0 if self._t is None else t - self._t
        if self._t is not None and not dt > 0:
            raise ValueError(f"time must increase: {t} after {self._t}")
        cfg = self.config
        fault = ""
        if dt > cfg.max_gap_s:
            self._start_filters()
            self.restarts += 1
            fault, dt = "gap", 0.0
        if self._t is None and self._heel_settle > 0.0:
            self._heel_masked_until, self._heel_settle = t + self._heel_settle, 0.0
        self._t = t
        z = self._z
        z[:] = raw
        implausible = _kernels.screen(z, self._lo, self._hi)
        self.implausible += implausible
        if not heel_filtered:  # both heel positions, when both are present (restarts rather than stick on NaN)
            self.highpass.step_inplace(self._heel)
        if self._any_unmodelled:
            z[self._unmodelled] = np.nan
        if t < self._heel_masked_until:  # after a restart, until the heel high-pass has settled
            z[Z_HEEL_FORWARD : Z_HEEL_UP + 1] = np.nan
        if heel_strike is None:
            angle, vel = float(z[Z_FOOT_ANGLE]), float(z[Z_FOOT_VEL])
            heel_strike = math.isfinite(angle) and math.isfinite(vel) and self.detector.detect(t, dt, angle, vel)
        if dt > 0:
            self.ekf.predict(dt)
            self.tbe.predict(dt)
        self.ekf.update(z)
        reset = self.backup.track(t, dt, z, heel_strike) if self.backup is not None else False
        if heel_strike:
            self.tbe.update(self._hs)
        if not self._healthy():
            self._reset_diverged()
            fault = "diverged"
        ekf = self.ekf
        stride_m = ekf.stride_length_norm * cfg.leg_length
        torque = 0.0
        if command and fault != "diverged":  # as the stack commands it: the stride in metres over the leg length
            torque = self.model.torque.torque_at(
                ekf.phase, stride_m / cfg.leg_length, ekf.incline, cfg.body_mass_kg * cfg.torque_gain, cfg.max_torque
            )
            if not 0.0 <= torque <= cfg.max_torque:  # NaN fails too
                torque, fault = 0.0, fault or "torque"
        x = ekf.x
        return _estimate(
            {
                "phase": float(x[0]),
                "phase_rate": float(x[1]),
                "stride_length_m": stride_m,
                "incline_deg": float(x[3]),
                "torque_Nm": torque,
                "heel_strike": heel_strike,
                "tbe_phase": self.tbe.phase,
                "backup_reset": reset,
                "fault": fault,
                "implausible": implausible,
            }
        )

    def run(
        self,
        t: Array,
        z: Array,
        heel_strike: NDArray[np.bool_] | None = None,
        heel_filtered: bool = False,
    ) -> dict[str, NDArray[np.generic]]:
        """Process a whole batch of samples at once: :meth:`step` for each, in one compiled loop.

        The outputs equal those of calling :meth:`step` sample by sample (same operations in the same
        order), and the pipeline is left in the same state, so ``run`` and ``step`` calls may be mixed.
        Unlike a loop of ``step``, the times are all checked before any sample is processed.

        Args:
            t: ``(n,)`` time stamps (s), finite and strictly increasing (also after the last step).
            z: ``(n, 6)`` raw measurements as for :meth:`step`; NaN where a sensor is missing.
            heel_strike: ``(n,)`` given heel strikes, or None to detect them all from the foot signals.
            heel_filtered: the heel positions were already high-passed.

        Returns:
            One ``(n,)`` array per :class:`GaitEstimate` field: ``phase``, ``phase_rate``,
            ``stride_length_m``, ``incline_deg``, ``torque_Nm``, ``tbe_phase`` (float), ``heel_strike``,
            ``backup_reset`` (bool), ``fault`` (str) and ``implausible`` (int).

        Raises:
            ValueError: a non-finite or non-increasing time, or arrays of the wrong shape.
        """
        return _batch.run(self, t, z, heel_strike, heel_filtered)

    def restart(self, initial: Array | None = None, heel_settle_s: float = 0.0) -> None:
        """Restart every filter (the walker starts again), keeping the tuning: the EKF from ``initial``
        (``[p, pdot, lp, r]``; None: its initial state). The next :meth:`step` is the first of a new
        stream (no prediction over the time since the last one, and no gap). For ``heel_settle_s`` from it
        the EKF does not use the heel positions: their high-pass filter starts again too, and its output
        means nothing until it has settled (its time constant is about 1 / (2 pi 0.5 Hz) x 2)."""
        self._start_filters()
        self.restarts += 1
        self._t = None
        self._heel_settle = heel_settle_s
        if initial is not None:
            self.ekf.reset(np.asarray(initial, dtype=np.float64), self.config.ekf.initial_covariance())

    def reset_from_backup(self) -> None:
        """Reset the EKF from the heel-strike backup, else the timing-based estimate (as after divergence)."""
        self._reset_diverged()

    def _healthy(self) -> bool:
        """The EKF's state and covariance are finite and within :class:`HealthLimits`."""
        lim = self.config.health
        return bool(
            _kernels.healthy(
                self.ekf.x, self.ekf.P, lim.min_phase_rate, lim.max_phase_rate, lim.max_abs_incline, lim.max_variance
            )
        )

    def _reset_diverged(self) -> None:
        """Reset a diverged EKF from the backup, else the timing-based estimate, else its start."""
        self.resets += 1
        cfg = self.config.ekf
        start = cfg.initial_state()
        candidates = []
        if self.backup is not None:
            b = self.backup
            candidates.append(np.array([b.phase, b.phase_rate, b.x[0], b.x[1]]))
        candidates.append(np.array([self.tbe.phase, self.tbe.x[1], start[2], start[3]]))
        lim = self.config.health
        for x in candidates:
            if np.all(np.isfinite(x)) and lim.min_phase_rate <= x[1] <= lim.max_phase_rate:
                if abs(x[3]) <= lim.max_abs_incline:
                    self.ekf.reset(x, cfg.initial_covariance())
                    break
        else:
            self.ekf.reset(start, cfg.initial_covariance())
        if self.backup is not None and not (np.all(np.isfinite(self.backup.x)) and np.all(np.isfinite(self.backup.P))):
            self.backup = HeelStrikeBackup(self.ekf, self.model.noise, self.config.backup)

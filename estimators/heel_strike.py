"""Heel-strike backup filter (seed 000 section II-D).

The backup runs beside the main EKF. Its phase runs open loop from the last heel strike at the rate
of the last stride; a two-state EKF over ``[lp, r]`` uses that phase to track stride length and
incline. Both filters accumulate ``SSE += y^T Rbar^-1 y`` (``y`` the innovation at the prior, ``Rbar``
the phase average of ``Sigma_R``). At each heel strike, if ``SSE_EKF - SSE_HP`` exceeds a margin
(1.2e3 in the authors' code) the main EKF is overwritten with the backup's estimate and
``P = 1e-3 I``; both sums then restart. Order per sample: EKF predict, EKF update, backup, read.

The backup also implements the stack interface (:mod:`gaitscope.estimators.protocol`) on its own
(:meth:`HeelStrikeBackup.standalone`, ``hs_backup``): its ``[lp, r]`` filter then takes ``Sigma_R`` at
its own phase and there is no main EKF to compare with or reset. Inside
:class:`~gaitscope.estimators.pipeline.GaitStatePipeline` it stays coupled to the EKF as the paper describes
(:meth:`HeelStrikeBackup.track`).

Heel-strike detection is :mod:`estimators.detector`, the timing-based estimate :mod:`estimators.tbe`;
both are re-exported here, where they used to live.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

import numpy as np
from numpy.typing import NDArray

from gaitscope.estimators import _kernels
from gaitscope.estimators.basis import Array
from gaitscope.estimators.channels import positions, span
from gaitscope.estimators.descriptor import Descriptor, Tunable, out
from gaitscope.estimators.detector import DetectorConfig, HeelStrikeDetector
from gaitscope.estimators.gait_model import N_CHANNELS, N_OUTPUTS, NoiseModel
from gaitscope.estimators.phase_ekf import EKFConfig, PhaseEKF, pseudo_from_stride, stride_from_pseudo
from gaitscope.estimators.protocol import HEEL_STRIKE, MAX_GAP_S, Output, check_params, elapsed
from gaitscope.estimators.tbe import TimingBasedEstimator

__all__ = [
    "DESCRIPTOR",
    "BackupConfig",
    "DetectorConfig",
    "HeelStrikeBackup",
    "HeelStrikeDetector",
    "TimingBasedEstimator",
]

_INPUTS: Final = (HEEL_STRIKE,)
_OPTIONAL: Final = ("foot_angle_deg", "foot_vel_dps", "shank_angle_deg", "shank_vel_dps")
#: Where :meth:`HeelStrikeBackup.step` finds each channel in ``z`` (its inputs, then its optional inputs): the
#: heel strike, and the block of the EKF's first four measurement channels.
(_HS,) = positions((*_INPUTS, *_OPTIONAL), HEEL_STRIKE)
_SENSORS: Final = span((*_INPUTS, *_OPTIONAL), "foot_angle_deg", "foot_vel_dps", "shank_angle_deg", "shank_vel_dps")


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

    Coupled (``HeelStrikeBackup(ekf, noise, config)``, what the pipeline runs): :meth:`track` after each
    main-EKF update, with the EKF's ``Sigma_R``, comparing the two filters' innovations and resetting the
    EKF at a heel strike when the backup did better. Standalone (:meth:`standalone`): a stack estimator of
    its own (``hs_backup``): ``Sigma_R`` at its own phase, no EKF to compare with or reset.

    Attributes:
        x: ``[lp, r]``; P: ``(2, 2)``; phase, phase_rate: the open-loop phase; resets: count.
    """

    name = "hs_backup"
    inputs: tuple[str, ...] = _INPUTS
    #: Angles and angular velocities only: heel positions need the high-pass the phase EKF stack runs.
    optional_inputs: tuple[str, ...] = _OPTIONAL
    outputs: tuple[Output, ...] = (
        ("phase", "1"),
        ("phase_rate", "1/s"),
        ("stride_length_m", "m"),
        ("incline_deg", "deg"),
    )
    tunables: tuple[str, ...] = ("measurement_noise_scale",)

    def __init__(
        self,
        ekf: PhaseEKF | None,
        noise: NoiseModel,
        config: BackupConfig | None = None,
        *,
        coef: Array | None = None,
        leg_length: float | None = None,
        ekf_config: EKFConfig | None = None,
        channel_mask: NDArray[np.bool_] | None = None,
        max_gap_s: float = MAX_GAP_S,
    ):
        self.config = config or BackupConfig()
        self.ekf = ekf
        if ekf is not None:
            coef, leg_length, ekf_config = ekf.coef, ekf.leg_length, ekf.config
        if coef is None or leg_length is None:
            raise ValueError("a standalone backup needs the gait model's coefficients and the leg length")
        self._coef = np.ascontiguousarray(coef, dtype=np.float64)
        self._leg_length = float(leg_length)
        self._ekf_config = ekf_config or EKFConfig()
        self._noise = noise
        self._mask = None if channel_mask is None else ~np.asarray(channel_mask, dtype=bool)
        self.max_gap_s = max_gap_s
        self._scale = self._ekf_config.measurement_noise_scale
        self._bins = np.ascontiguousarray(noise.bins * self._scale)
        self._R = np.zeros((N_CHANNELS, N_CHANNELS))
        self._z = np.full(N_CHANNELS, np.nan)
        self._t: float | None = None
        self._work = np.zeros(4 + N_OUTPUTS * 7 + N_CHANNELS * 7)  # _kernels.backup_update's scratch
        self._no_ekf_y = np.zeros(0)
        self._y = np.zeros(N_CHANNELS)
        self._S = np.zeros((N_CHANNELS, N_CHANNELS))
        self._K = np.zeros((2, N_CHANNELS))
        self._start()
        self.resets = 0

    @classmethod
    def standalone(
        cls,
        coef: Array,
        noise: NoiseModel,
        leg_length: float,
        ekf_config: EKFConfig | None = None,
        config: BackupConfig | None = None,
        channel_mask: NDArray[np.bool_] | None = None,
    ) -> HeelStrikeBackup:
        """The backup as a stack estimator of its own (``channel_mask``: the channels the model predicts)."""
        return cls(
            None, noise, config, coef=coef, leg_length=leg_length, ekf_config=ekf_config, channel_mask=channel_mask
        )

    def _start(self) -> None:
        """The initial state (the EKF's initial stride length and incline), keeping the tuning."""
        ekf_cfg = self._ekf_config
        self.x = np.array([pseudo_from_stride(ekf_cfg.initial_stride_length), ekf_cfg.initial_incline])
        self.P = self.config.p0 * np.eye(2)
        self.phase = 0.0
        self.phase_rate = 1.0 / self.config.initial_period
        self.sse_ekf = 0.0
        self.sse_hp = 0.0
        self._rbar = np.ascontiguousarray(self._noise.mean() * self._current_scale())
        self._last_hs: float | None = None

    def _current_scale(self) -> float:
        return self.ekf.config.measurement_noise_scale if self.ekf is not None else self._scale

    def retune(self, **params: float) -> None:
        """Follow the noise scale: coupled, the main EKF's (after :meth:`PhaseEKF.retune`, no argument);
        standalone, ``measurement_noise_scale``."""
        check_params(self, params)
        if "measurement_noise_scale" in params:
            scale = float(params["measurement_noise_scale"])
            if not scale > 0:
                raise ValueError(f"measurement_noise_scale must be positive, got {scale}")
            self._scale = scale
            self._bins = np.ascontiguousarray(self._noise.bins * scale)
        self._rbar = np.ascontiguousarray(self._noise.mean() * self._current_scale())

    def reset(self) -> None:
        """Back to the initial state (the stack interface); the tuning is kept."""
        self._start()
        self._t = None

    @property
    def state(self) -> NDArray[np.float64]:
        return self.x

    @property
    def covariance(self) -> NDArray[np.float64]:
        return self.P

    def step(self, t: float, z: NDArray[np.float64]) -> NDArray[np.float64]:
        """The stack interface: ``z`` = heel strike, foot angle, foot velocity, shank angle, shank
        velocity; returns phase, phase rate, stride length (m) and incline (deg)."""
        dt, restart = elapsed(self._t, t, self.max_gap_s)
        if restart:
            self._start()
        self._t = t
        zz = self._z
        zz[:4] = z[_SENSORS]
        if self._mask is not None:
            zz[self._mask] = np.nan
        self.track(t, dt, zz, bool(z[_HS] > 0.5))
        return np.array(
            [self.phase, self.phase_rate, self._leg_length * stride_from_pseudo(float(self.x[0])), self.x[1]]
        )

    def track(self, t: float, dt: float, z: Array | None, heel_strike: bool) -> bool:
        """Advance to the sample at time ``t``; coupled, run after the main EKF's update. True if it
        reset the EKF (coupled only)."""
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
        ekf = self.ekf
        if z is not None:  # h, H, R (standalone: at its own phase), the update and both SSE terms, compiled
            sse_hp, sse_ekf = _kernels.backup_update(
                self._coef,
                self._leg_length,
                self.phase,
                self.phase_rate,
                self.x,
                self.P,
                z,
                self._bins,
                self._R if ekf is None else ekf.R,
                ekf is None,
                self._rbar,
                self._no_ekf_y if ekf is None else ekf.y,
                self._work,
                self._y,
                self._S,
                self._K,
            )
            self.sse_hp += sse_hp
            if ekf is not None:
                self.sse_ekf += sse_ekf
        reset = False
        if heel_strike:
            if ekf is not None and self.sse_ekf - self.sse_hp > cfg.sse_margin:
                ekf.reset(np.array([self.phase, self.phase_rate, self.x[0], self.x[1]]), cfg.reset_p * np.eye(4))
                self.resets += 1
                reset = True
            self.sse_ekf = self.sse_hp = 0.0
        return reset


#: The standalone heel-strike backup as a session and the views know it
#: (:mod:`gaitscope.estimators.descriptor`): run only when named (it duplicates the one inside ``phase_ekf``).
DESCRIPTOR: Final = Descriptor(
    name=HeelStrikeBackup.name,
    label="Heel-strike backup",
    inputs=HeelStrikeBackup.inputs,
    optional_inputs=HeelStrikeBackup.optional_inputs,
    outputs=(
        out("phase", "1", "gait phase, 0 at heel strike, 1 at the next"),
        out("phase_rate", "1/s", "gait cycles per second"),
        out("stride_length_m", "m", "stride length"),
        out("incline_deg", "deg", "ground incline, (+) uphill"),
    ),
    quantities={
        "phase": "phase",
        "phase_rate": "phase_rate",
        "stride_length_m": "stride_length",
        "incline_deg": "incline",
    },
    tunables=(Tunable("measurement_noise_scale"),),
    opt_in=True,
    purpose="The phase EKF's heel-strike backup on its own (phase open loop from the last heel strike), to compare.",
    paper="Medrano et al., IEEE T-RO 2023 (seed 000)",
)

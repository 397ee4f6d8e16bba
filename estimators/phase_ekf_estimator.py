"""The seed-000 phase EKF stack (:class:`~gaitscope.estimators.pipeline.GaitStatePipeline`) as a stack estimator.

``phase_ekf`` in a session's stack: heel high-pass, heel-strike detection (unless the heel-strike channel
is given), phase EKF, heel-strike backup, divergence reset and gap restart, exactly as the pipeline runs
them for ``gaitscope replay`` and the cross-validation (same object, same numbers). The torque is not
among its outputs: the session's stack computes it from its primary estimator's outputs.

Outputs: ``phase`` (cycles, [0, 1)), ``phase_rate`` (1/s), ``stride_length_m``, ``incline_deg``,
``heel_strike`` and ``backup_reset`` (1.0 / 0.0), ``fault`` (a code of
:data:`~gaitscope.estimators.protocol.FAULTS`: 1 the filters restarted after a gap, 2 the EKF diverged and was
reset), and ``foot_pred_deg``, ``shank_pred_deg``, the gait model at the prior (0 where not finite).
``state`` and ``covariance`` are the EKF's ``x = [p, pdot, lp, r]`` and ``P``.
"""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from numpy.typing import NDArray

from gaitscope.estimators.channels import positions, span
from gaitscope.estimators.descriptor import Descriptor, Tunable, out
from gaitscope.estimators.lock import LockConfig, LockSupervisor
from gaitscope.estimators.pipeline import GaitStatePipeline, PipelineConfig, TrainedModel
from gaitscope.estimators.protocol import HEEL_STRIKE, SENSOR_CHANNELS, Output, check_params

__all__ = ["DESCRIPTOR", "PhaseEKFEstimator"]

#: The pipeline's faults as :data:`~gaitscope.estimators.protocol.FAULTS` codes; its own torque is not an output.
_FAULT_CODE = {"": 0.0, "gap": 1.0, "diverged": 2.0, "torque": 0.0}
_LOST, _RESUMED = 4.0, 5.0  # FAULTS.index("lost"), FAULTS.index("resumed")
_INPUTS: Final = ()
_OPTIONAL: Final = (*SENSOR_CHANNELS, HEEL_STRIKE)
#: It runs on a foot angle or a shank angle, or both (:attr:`PhaseEKFEstimator.inputs_any`).
_ANY: Final = ("foot_angle_deg", "shank_angle_deg")
#: Where :meth:`PhaseEKFEstimator.step` finds each channel in ``z`` (its inputs, then its optional inputs),
#: and the pipeline's measurement vector there (:data:`~gaitscope.estimators.protocol.SENSOR_CHANNELS`).
_FOOT, _FOOT_VEL, _SHANK_VEL, _HS = positions(
    (*_INPUTS, *_OPTIONAL), "foot_angle_deg", "foot_vel_dps", "shank_vel_dps", HEEL_STRIKE
)
_SENSORS: Final = span((*_INPUTS, *_OPTIONAL), *SENSOR_CHANNELS)


class PhaseEKFEstimator:
    """:class:`~gaitscope.estimators.pipeline.GaitStatePipeline` behind the stack interface (``phase_ekf``).

    Args:
        model: the trained models.
        config: the pipeline's settings (its torque settings are unused: the stack computes the torque).
        sample_period: nominal sample period (s) of the heel high-pass filter.

    Attributes:
        pipeline: the pipeline it runs (replaced by a fresh one on :meth:`reset`).
    """

    name = "phase_ekf"
    #: No channel is required alone: it needs a foot angle or a shank angle (:attr:`inputs_any`) and uses
    #: whatever else is present (measurement subsets, seed 000 II-C3). With the foot angle, heel strikes
    #: come from it (seed 000); without it, the lock supervisor finds them in the shank angle
    #: (:mod:`gaitscope.estimators.lock`), as a single shank IMU's device gives them.
    inputs: tuple[str, ...] = _INPUTS
    optional_inputs: tuple[str, ...] = _OPTIONAL
    inputs_any: tuple[str, ...] = _ANY
    outputs: tuple[Output, ...] = (
        ("phase", "1"),
        ("phase_rate", "1/s"),
        ("stride_length_m", "m"),
        ("incline_deg", "deg"),
        (HEEL_STRIKE, "bool"),
        ("backup_reset", "bool"),
        ("fault", "code"),
        ("foot_pred_deg", "deg"),
        ("shank_pred_deg", "deg"),
        ("standing", "1"),
    )
    tunables: tuple[str, ...] = ("measurement_noise_scale", "process_noise_scale")

    def __init__(
        self,
        model: TrainedModel,
        config: PipelineConfig | None = None,
        sample_period: float = 0.01,
        lock: LockConfig | None = None,
    ):
        self._model = model
        self._sample_period = sample_period
        self.pipeline = GaitStatePipeline(model, config, sample_period)
        self.supervisor = LockSupervisor(lock)
        #: why the filter last lost track (empty: never)
        self.lost_reason = ""
        self._walking: NDArray[np.float64] | None = None  # the EKF's state at the last sample walking
        self._t: float | None = None  # the last sample's time
        #: the phase rate's extra process variance per second while the cadence changes (``rate_noise_scale``)
        self._rate_q = _rate_q(self.pipeline.config, self.supervisor.config)

    def reset(self) -> None:
        """A fresh pipeline with the current tuning."""
        self.pipeline = GaitStatePipeline(self._model, self.pipeline.config, self._sample_period)
        self.supervisor.reset()
        self._walking = None
        self._t = None

    def retune(self, **params: float) -> None:
        """``measurement_noise_scale`` and ``process_noise_scale`` (x ``Sigma_R`` and x ``Q``)."""
        check_params(self, params)
        self.pipeline.retune(
            measurement_noise_scale=params.get("measurement_noise_scale"),
            process_noise_scale=params.get("process_noise_scale"),
        )
        self._rate_q = _rate_q(self.pipeline.config, self.supervisor.config)

    @property
    def config(self) -> PipelineConfig:
        return self.pipeline.config

    @property
    def state(self) -> NDArray[np.float64]:
        return self.pipeline.ekf.x

    @property
    def covariance(self) -> NDArray[np.float64]:
        return self.pipeline.ekf.P

    def step(self, t: float, z: NDArray[np.float64]) -> NDArray[np.float64]:
        """``z``: the six sensor channels (raw heel positions) then the heel strike (NaN: detect it)."""
        p, sup = self.pipeline, self.supervisor
        dt = 0.0 if self._t is None else t - self._t
        self._t = t
        foot, foot_dps, shank_dps, hs = float(z[_FOOT]), float(z[_FOOT_VEL]), float(z[_SHANK_VEL]), float(z[_HS])
        event = sup.motion(t, foot_dps, shank_dps, p.ekf.phase)
        if sup.standing:  # phase held, rate 0, the filters wait (they restart when walking resumes)
            ekf, pred = p.ekf, p.predicted
            l_m = ekf.stride_length_norm * p.config.leg_length
            held, held_rate = sup.held_phase, 0.0
            if sup.config.advance_at_onset and sup.onset is not None:  # moving: as the restart would start
                x0 = self._resume_state(t)
                held, held_rate = float(x0[0]) % 1.0, float(x0[1])
            return np.array([held, held_rate, _finite(l_m), _finite(ekf.incline), 0.0, 0.0, 0.0,
                             _finite(pred[0]), _finite(pred[2]), sup.standing_weight])  # fmt: skip
        shank_hs = sup.shank.step(shank_dps)
        given = None if math.isnan(hs) else bool(hs > 0.5)
        if given is None and math.isnan(foot) and not math.isnan(shank_dps) and sup.config.enabled:
            given = shank_hs  # no foot sensor to detect heel strikes from: the shank's
        if event == "resumed":  # start again at the cadence, stride and slope of the walking before
            p.restart(self._resume_state(t), sup.config.heel_settle_s)
        e = p.step(t, z[_SENSORS], given, command=False)  # the stack commands the torque
        fault = _RESUMED if event == "resumed" else _FAULT_CODE[e.fault]
        why = sup.lost(t, e.heel_strike, e.phase_rate)
        phase, rate = e.phase, e.phase_rate
        if why and not e.fault:
            p.reset_from_backup()
            self.lost_reason, fault = f"lost track at {t:.2f} s ({why})", _LOST
            phase, rate = p.ekf.phase, p.ekf.phase_rate
        if sup.adapting(t, e.heel_strike):  # the cadence changes: the phase rate follows it faster
            p.ekf.P[1, 1] += self._rate_q * dt
        lo, hi = sup.config.phase_rate_range
        if e.heel_strike and lo <= rate <= hi:  # the cadence, stride and slope at the last heel strike walking
            self._walking = p.ekf.x.copy()
        pred = p.predicted
        return np.array(
            [
                phase,
                rate,
                e.stride_length_m,
                e.incline_deg,
                1.0 if e.heel_strike else 0.0,
                1.0 if e.backup_reset else 0.0,
                fault,
                _finite(pred[0]),
                _finite(pred[2]),
                sup.standing_weight,
            ]
        )

    def _resume_state(self, t: float) -> NDArray[np.float64]:
        """The EKF's state walking resumes from at ``t``: the posture's phase (``resume_phase``) at the cadence,
        stride and slope of the last heel strike walked, advanced by that cadence since the motion's onset
        (``backdate_resume``; at most ``still_s``)."""
        sup = self.supervisor
        x0 = self.pipeline.config.ekf.initial_state() if self._walking is None else self._walking.copy()
        x0[0] = sup.config.resume_phase
        if sup.config.backdate_resume and sup.onset is not None:  # walking began when the motion did
            x0[0] += min(t - sup.onset, sup.config.still_s) * x0[1]
        return x0


def _rate_q(config: PipelineConfig, lock: LockConfig) -> float:
    """The phase rate's extra process variance per second while the cadence changes: the filter's own
    (``q_std[0]^2 / q_time_unit``, times its ``process_noise_scale``) times ``rate_noise_scale^2 - 1``."""
    ekf, f = config.ekf, lock.rate_noise_scale
    return (f * f - 1.0) * (ekf.q_std[0] * ekf.q_std[0] / ekf.q_time_unit) * ekf.process_noise_scale


def _finite(v: float) -> float:
    v = float(v)
    return v if math.isfinite(v) else 0.0


#: The phase EKF as a session and the views know it (:mod:`gaitscope.estimators.descriptor`); the noise
#: scales are the session's settings (``SessionSettings``), within their bounds there.
DESCRIPTOR: Final = Descriptor(
    name=PhaseEKFEstimator.name,
    label="Phase EKF (seed 000)",
    inputs=PhaseEKFEstimator.inputs,
    optional_inputs=PhaseEKFEstimator.optional_inputs,
    inputs_any=PhaseEKFEstimator.inputs_any,
    outputs=(
        out("phase", "1", "gait phase, 0 at heel strike, 1 at the next"),
        out("phase_rate", "1/s", "gait cycles per second"),
        out("stride_length_m", "m", "stride length"),
        out("incline_deg", "deg", "ground incline, (+) uphill"),
        out(HEEL_STRIKE, "bool"),
        out("backup_reset", "bool", "the heel-strike backup reset the filter on this sample"),
        out("fault", "code", "a fault code (gaitscope.estimators.protocol.FAULTS)"),
        out("foot_pred_deg", "deg", "the model's foot angle at the estimated state"),
        out("shank_pred_deg", "deg", "the model's shank angle at the estimated state"),
        out("standing", "1", "1 while the walker stands still (the phase is held)"),
    ),
    quantities={
        "phase": "phase",
        "phase_rate": "phase_rate",
        "stride_length_m": "stride_length",
        "incline_deg": "incline",
    },
    tunables=(Tunable("measurement_noise_scale", 0.1, 10.0), Tunable("process_noise_scale", 0.1, 10.0)),
    purpose="Gait phase, stride length and incline from a foot or shank angle: the torque follows it by default.",
    paper="Medrano et al., IEEE T-RO 2023 (seed 000)",
)

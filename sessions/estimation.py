"""Sensor frames in, gait states out: the estimator stack as a device stream needs it.

Used live by :class:`~sessions.runtime.SessionRuntime`, and offline to re-run recordings and to import
raw logs (:func:`estimate`).
"""

from __future__ import annotations

import math

import numpy as np

from estimators.pipeline import GaitStatePipeline, PipelineConfig, TrainedModel
from sessions.schema import GaitState, SensorFrame, SessionSettings

#: Assumed sample period until the source's rate is known (s).
DEFAULT_PERIOD = 0.005


class FrameEstimator:
    """Sensor frames in, gait states out: the pipeline plus what a device stream needs around it.

    Session time starts at 0 on the first frame (or is ``frame.t - time_origin`` when given);
    angular velocities a device does not send are derived by backward difference; ``foot_pred_deg``
    and ``shank_pred_deg`` are the gait model at the prior estimate (what the filter expected to
    measure). Used live and for offline re-runs.
    """

    def __init__(
        self,
        model: TrainedModel,
        leg_length: float,
        mass_kg: float,
        settings: SessionSettings,
        sample_period: float = DEFAULT_PERIOD,
        time_origin: float | None = None,
    ):
        self.pipeline = GaitStatePipeline(
            model,
            PipelineConfig(
                leg_length=leg_length,
                body_mass_kg=mass_kg,
                torque_gain=settings.torque_gain,
                max_torque=settings.max_torque_Nm,
            ),
            sample_period=sample_period,
        )
        self.retune(settings)
        self.last_t = 0.0
        self._t_offset = time_origin
        self._prev: SensorFrame | None = None

    def retune(self, s: SessionSettings) -> None:
        self.pipeline.retune(
            torque_gain=s.torque_gain,
            max_torque=s.max_torque_Nm,
            measurement_noise_scale=s.measurement_noise_scale,
            process_noise_scale=s.process_noise_scale,
        )

    def accepts(self, frame: SensorFrame) -> bool:
        """True if ``frame`` comes after the last frame stepped (or is the first)."""
        return self._prev is None or self._t_offset is None or frame.t - self._t_offset > self.last_t

    def step(self, frame: SensorFrame, recv_ns: int) -> GaitState:
        if self._t_offset is None:
            self._t_offset = frame.t
        t = frame.t - self._t_offset
        if self._prev is not None and not t > self.last_t:
            raise ValueError(f"frame time {frame.t} does not increase")
        raw = np.array(
            [
                _or_nan(frame.foot_angle_deg),
                _or_nan(frame.foot_vel_dps),
                _or_nan(frame.shank_angle_deg),
                _or_nan(frame.shank_vel_dps),
                _or_nan(frame.heel_forward_m),
                _or_nan(frame.heel_up_m),
            ]
        )
        self._derive_velocities(raw, t)
        e = self.pipeline.step(t, raw, frame.heel_strike)
        pred = self.pipeline.predicted
        self.last_t = t
        self._prev = frame.model_copy(update={"t": t})
        return GaitState(
            seq=frame.seq,
            t=t,
            phase=e.phase,
            phase_rate=e.phase_rate,
            stride_length_m=e.stride_length_m,
            incline_deg=e.incline_deg,
            torque_Nm=e.torque_Nm,
            tbe_phase=e.tbe_phase,
            heel_strike=e.heel_strike,
            backup_reset=e.backup_reset,
            foot_angle_deg=frame.foot_angle_deg,
            shank_angle_deg=frame.shank_angle_deg,
            thigh_angle_deg=frame.thigh_angle_deg,
            foot_pred_deg=float(pred[0]),
            shank_pred_deg=float(pred[2]),
            sent_ns=frame.sent_ns,
            recv_ns=recv_ns,
        )

    def _derive_velocities(self, raw: np.ndarray, t: float) -> None:
        """Backward-difference velocities for a device without gyroscopes."""
        prev = self._prev
        for angle_i, vel_i, name in ((0, 1, "foot_angle_deg"), (2, 3, "shank_angle_deg")):
            if math.isnan(raw[vel_i]) and not math.isnan(raw[angle_i]) and prev is not None:
                before = getattr(prev, name)
                if before is not None and t > prev.t:
                    raw[vel_i] = (raw[angle_i] - before) / (t - prev.t)


def estimate(
    frames: list[SensorFrame],
    model: TrainedModel,
    leg_length: float,
    mass_kg: float,
    settings: SessionSettings,
    time_origin: float | None = None,
) -> list[GaitState]:
    """Run recorded frames through a fresh estimator (review re-runs, imports of raw logs).

    Recorded ``/sensor`` frames carry session time, so a re-run passes ``time_origin=0`` to keep it.
    """
    period = (frames[-1].t - frames[0].t) / (len(frames) - 1) if len(frames) > 1 else DEFAULT_PERIOD
    est = FrameEstimator(model, leg_length, mass_kg, settings, period, time_origin)
    return [est.step(f, 0) for f in frames]


def _or_nan(v: float | None) -> float:
    return math.nan if v is None else v

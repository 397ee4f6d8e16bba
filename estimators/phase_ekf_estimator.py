"""The seed-000 phase EKF stack (:class:`~estimators.pipeline.GaitStatePipeline`) as a stack estimator.

``phase_ekf`` in a session's stack: heel high-pass, heel-strike detection (unless the heel-strike channel
is given), phase EKF, heel-strike backup, divergence reset and gap restart, exactly as the pipeline runs
them for ``gaitscope replay`` and the cross-validation (same object, same numbers). The torque is not
among its outputs: the session's stack computes it from its primary estimator's outputs.

Outputs: ``phase`` (cycles, [0, 1)), ``phase_rate`` (1/s), ``stride_length_m``, ``incline_deg``,
``heel_strike`` and ``backup_reset`` (1.0 / 0.0), ``fault`` (a code of
:data:`~estimators.protocol.FAULTS`: 1 the filters restarted after a gap, 2 the EKF diverged and was
reset), and ``foot_pred_deg``, ``shank_pred_deg``, the gait model at the prior (0 where not finite).
``state`` and ``covariance`` are the EKF's ``x = [p, pdot, lp, r]`` and ``P``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from estimators.pipeline import GaitStatePipeline, PipelineConfig, TrainedModel
from estimators.protocol import HEEL_STRIKE, SENSOR_CHANNELS, Output, check_params

__all__ = ["PhaseEKFEstimator"]

#: The pipeline's faults as :data:`~estimators.protocol.FAULTS` codes; its own torque is not an output.
_FAULT_CODE = {"": 0.0, "gap": 1.0, "diverged": 2.0, "torque": 0.0}


class PhaseEKFEstimator:
    """:class:`~estimators.pipeline.GaitStatePipeline` behind the stack interface (``phase_ekf``).

    Args:
        model: the trained models.
        config: the pipeline's settings (its torque settings are unused: the stack computes the torque).
        sample_period: nominal sample period (s) of the heel high-pass filter.

    Attributes:
        pipeline: the pipeline it runs (replaced by a fresh one on :meth:`reset`).
    """

    name = "phase_ekf"
    #: The foot angle drives heel-strike detection and is what every trained model predicts first; the
    #: EKF uses whatever else is present (measurement subsets, seed 000 II-C3).
    inputs: tuple[str, ...] = ("foot_angle_deg",)
    optional_inputs: tuple[str, ...] = (*SENSOR_CHANNELS[1:], HEEL_STRIKE)
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
    )
    tunables: tuple[str, ...] = ("measurement_noise_scale", "process_noise_scale")

    def __init__(self, model: TrainedModel, config: PipelineConfig | None = None, sample_period: float = 0.01):
        self._model = model
        self._sample_period = sample_period
        self.pipeline = GaitStatePipeline(model, config, sample_period)

    def reset(self) -> None:
        """A fresh pipeline with the current tuning."""
        self.pipeline = GaitStatePipeline(self._model, self.pipeline.config, self._sample_period)

    def retune(self, **params: float) -> None:
        """``measurement_noise_scale`` and ``process_noise_scale`` (x ``Sigma_R`` and x ``Q``)."""
        check_params(self, params)
        self.pipeline.retune(
            measurement_noise_scale=params.get("measurement_noise_scale"),
            process_noise_scale=params.get("process_noise_scale"),
        )

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
        hs = z[6]
        e = self.pipeline.step(t, z[:6], None if math.isnan(hs) else bool(hs > 0.5))
        pred = self.pipeline.predicted
        return np.array(
            [
                e.phase,
                e.phase_rate,
                e.stride_length_m,
                e.incline_deg,
                1.0 if e.heel_strike else 0.0,
                1.0 if e.backup_reset else 0.0,
                _FAULT_CODE[e.fault],
                _finite(pred[0]),
                _finite(pred[2]),
            ]
        )


def _finite(v: float) -> float:
    v = float(v)
    return v if math.isfinite(v) else 0.0

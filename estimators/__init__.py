"""gaitscope estimators: pure numerical gait-state estimation (no I/O, no clocks, no web types).

Seed 000 (Medrano et al. 2023): the gait model, the phase EKF, the heel-strike backup filter, the
timing-based baseline and the biomimetic torque profile, with one streaming pipeline around them. Every
estimator a session can stack implements :class:`~gaitscope.estimators.protocol.Estimator`.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from gaitscope.estimators.detector import DetectorConfig, HeelStrikeDetector
    from gaitscope.estimators.gait_model import CHANNELS, NoiseModel
    from gaitscope.estimators.heel_strike import BackupConfig, HeelStrikeBackup
    from gaitscope.estimators.highpass import HighPassFilter
    from gaitscope.estimators.phase_ekf import EKFConfig, PhaseEKF
    from gaitscope.estimators.phase_ekf_estimator import PhaseEKFEstimator
    from gaitscope.estimators.pipeline import GaitEstimate, GaitStatePipeline, PipelineConfig, TrainedModel
    from gaitscope.estimators.protocol import Estimator
    from gaitscope.estimators.tbe import TimingBasedEstimator
    from gaitscope.estimators.torque import TorqueProfile

#: The module of each name of :data:`__all__`, imported on first use (PEP 562): a module that needs one
#: estimator (the wire schema needs the channel table) does not import them all, nor SciPy's signal
#: package with the high-pass filter (most of a second).
_LAZY = {
    "DetectorConfig": "detector",
    "HeelStrikeDetector": "detector",
    "CHANNELS": "gait_model",
    "NoiseModel": "gait_model",
    "BackupConfig": "heel_strike",
    "HeelStrikeBackup": "heel_strike",
    "HighPassFilter": "highpass",
    "EKFConfig": "phase_ekf",
    "PhaseEKF": "phase_ekf",
    "PhaseEKFEstimator": "phase_ekf_estimator",
    "GaitEstimate": "pipeline",
    "GaitStatePipeline": "pipeline",
    "PipelineConfig": "pipeline",
    "TrainedModel": "pipeline",
    "Estimator": "protocol",
    "TimingBasedEstimator": "tbe",
    "TorqueProfile": "torque",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(f"gaitscope.estimators.{_LAZY[name]}"), name)
    raise AttributeError(f"module 'gaitscope.estimators' has no attribute {name!r}")


__all__ = [
    "CHANNELS",
    "BackupConfig",
    "DetectorConfig",
    "EKFConfig",
    "Estimator",
    "GaitEstimate",
    "GaitStatePipeline",
    "HeelStrikeBackup",
    "HeelStrikeDetector",
    "HighPassFilter",
    "NoiseModel",
    "PhaseEKF",
    "PhaseEKFEstimator",
    "PipelineConfig",
    "TimingBasedEstimator",
    "TorqueProfile",
    "TrainedModel",
]

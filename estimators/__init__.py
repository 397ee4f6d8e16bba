"""gaitscope estimators: pure numerical gait-state estimation (no I/O, no clocks, no web types).

Seed 000 (Medrano et al. 2023): the gait model, the phase EKF, the heel-strike backup filter, the
timing-based baseline and the biomimetic torque profile, with one streaming pipeline around them. Every
estimator a session can stack implements :class:`~gaitscope.estimators.protocol.Estimator`.
"""

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

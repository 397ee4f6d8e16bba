"""gaitscope estimators: pure numerical gait-state estimation (no I/O, no clocks, no web types).

Seed 000 (Medrano et al. 2023): the gait model, the phase EKF, the heel-strike backup filter, the
timing-based baseline and the biomimetic torque profile, with one streaming pipeline around them. Every
estimator a session can stack implements :class:`~estimators.protocol.Estimator`.
"""

from estimators.detector import DetectorConfig, HeelStrikeDetector
from estimators.gait_model import CHANNELS, NoiseModel
from estimators.heel_strike import BackupConfig, HeelStrikeBackup
from estimators.highpass import HighPassFilter
from estimators.phase_ekf import EKFConfig, PhaseEKF
from estimators.phase_ekf_estimator import PhaseEKFEstimator
from estimators.pipeline import GaitEstimate, GaitStatePipeline, PipelineConfig, TrainedModel
from estimators.protocol import Estimator
from estimators.tbe import TimingBasedEstimator
from estimators.torque import TorqueProfile

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

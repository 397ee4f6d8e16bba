"""gaitscope estimators: pure numerical gait-state estimation (no I/O, no clocks, no web types).

Seed 000 (Medrano et al. 2023): the gait model, the phase EKF, the heel-strike backup filter, the
timing-based baseline and the biomimetic torque profile, with one streaming pipeline around them.
"""

from estimators.gait_model import CHANNELS, NoiseModel
from estimators.heel_strike import (
    BackupConfig,
    DetectorConfig,
    HeelStrikeBackup,
    HeelStrikeDetector,
    TimingBasedEstimator,
)
from estimators.highpass import HighPassFilter
from estimators.phase_ekf import EKFConfig, PhaseEKF
from estimators.pipeline import GaitEstimate, GaitStatePipeline, PipelineConfig, TrainedModel
from estimators.torque import TorqueProfile

__all__ = [
    "CHANNELS",
    "BackupConfig",
    "DetectorConfig",
    "EKFConfig",
    "GaitEstimate",
    "GaitStatePipeline",
    "HeelStrikeBackup",
    "HeelStrikeDetector",
    "HighPassFilter",
    "NoiseModel",
    "PhaseEKF",
    "PipelineConfig",
    "TimingBasedEstimator",
    "TorqueProfile",
    "TrainedModel",
]

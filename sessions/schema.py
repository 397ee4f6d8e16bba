"""The one place that names what crosses a file or a socket.

Every column of a LocoHub table gaitscope reads or writes, every column of the replay CSV, and the
metadata of a fitted-model file are defined here; readers, writers and (later) the server's wire
messages derive from these names so that they cannot drift apart.

LocoHub conventions (jmontp/LocoHub, ``docs/reference/biomechanical_standard.md``): one row per sample,
angles in radians, moments in N m, ``phase_ipsi`` in percent of the ipsilateral gait cycle (0 at heel
strike, 150 points per cycle in phase-indexed files), ``task_info`` a ``key:value,key:value`` string
holding at least ``speed_m_s`` and ``incline_deg``. Sagittal segment angles are viewed from the
subject's right with forward to the right and counter-clockwise positive: thigh and shank from
vertical (positive when the distal end is ahead of the proximal one), foot from horizontal (positive
toes up). With these signs ``foot = shank + ankle_dorsiflexion`` (seed 000: shank = foot - ankle).
"""

from __future__ import annotations

from typing import Final, Literal

from pydantic import BaseModel, ConfigDict, Field

# --- LocoHub table: metadata columns -------------------------------------------------------------
SUBJECT: Final = "subject"
SUBJECT_METADATA: Final = "subject_metadata"  # "leg_length_m:0.9,mass_kg:75,..."
TASK: Final = "task"  # level_walking | incline_walking | decline_walking
TASK_ID: Final = "task_id"
TASK_INFO: Final = "task_info"  # "speed_m_s:1.2,incline_deg:5.0"
STEP: Final = "step"  # stride index within one (subject, task_id)
PHASE_IPSI: Final = "phase_ipsi"  # percent, 0..100
TIME_S: Final = "time_s"

METADATA_COLUMNS: Final = (SUBJECT, SUBJECT_METADATA, TASK, TASK_ID, TASK_INFO, STEP, PHASE_IPSI)

# --- LocoHub table: signals ----------------------------------------------------------------------
THIGH_ANGLE: Final = "thigh_sagittal_angle_ipsi_rad"
SHANK_ANGLE: Final = "shank_sagittal_angle_ipsi_rad"
FOOT_ANGLE: Final = "foot_sagittal_angle_ipsi_rad"
HIP_ANGLE: Final = "hip_flexion_angle_ipsi_rad"
KNEE_ANGLE: Final = "knee_flexion_angle_ipsi_rad"
ANKLE_ANGLE: Final = "ankle_dorsiflexion_angle_ipsi_rad"
HIP_ANGLE_CONTRA: Final = "hip_flexion_angle_contra_rad"
HEEL_FORWARD: Final = "heel_forward_position_ipsi_m"  # in a frame moving with the walker
HEEL_UP: Final = "heel_vertical_position_ipsi_m"
ANKLE_MOMENT: Final = "ankle_dorsiflexion_moment_ipsi_Nm"  # (+) dorsiflexor, so push-off is negative
COM_POSITION: Final = ("com_forward_position_m", "com_lateral_position_m", "com_vertical_position_m")
COM_VELOCITY: Final = ("com_forward_velocity_m_s", "com_lateral_velocity_m_s", "com_vertical_velocity_m_s")
HEEL_STRIKE: Final = "heel_strike_ipsi"  # 1 on the sample of an ipsilateral heel strike
TOE_OFF: Final = "toe_off_ipsi"
HEEL_STRIKE_CONTRA: Final = "heel_strike_contra"
STEP_LENGTH: Final = "step_length_ipsi_m"  # ipsilateral step ending at this stride's heel strike

# --- Ground truth, per sample ------------------------------------------------------------------
PHASE_RATE: Final = "phase_rate_ipsi_1_s"  # 1 / stride duration
STRIDE_LENGTH: Final = "stride_length_m"
INCLINE: Final = "incline_deg"
SPEED: Final = "speed_m_s"

#: Columns a LocoHub table must have for gaitscope to train its gait model on it.
TRAINING_COLUMNS: Final = (
    SUBJECT,
    TASK_INFO,
    STEP,
    PHASE_IPSI,
    TIME_S,
    FOOT_ANGLE,
    SHANK_ANGLE,
    HEEL_FORWARD,
    HEEL_UP,
    ANKLE_MOMENT,
)

# --- Replay CSV (gaitscope replay) ---------------------------------------------------------------
REPLAY_TIME: Final = "time_s"
REPLAY_SIGNALS: Final = (
    "foot_angle_deg",
    "foot_vel_dps",
    "shank_angle_deg",
    "shank_vel_dps",
    "heel_forward_m",
    "heel_up_m",
)
REPLAY_ANGLES: Final = ("foot_angle_deg", "shank_angle_deg")
REPLAY_HEEL_STRIKE: Final = "heel_strike"
REPLAY_OUTPUT: Final = (
    "time_s",
    "phase",
    "phase_rate",
    "stride_length_m",
    "incline_deg",
    "torque_Nm",
    "heel_strike",
    "tbe_phase",
)


class ModelProvenance(BaseModel):
    """What a fitted gait model was trained on; stored in every model file."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    format_version: Literal[1] = 1
    gaitscope_version: str
    created_utc: str
    source: str = Field(description="'default-cohort' or the path of the LocoHub file")
    source_sha256: str = Field(description="hash of the training table's signal columns")
    subjects: tuple[str, ...]
    n_samples: int = Field(ge=1)
    n_strides: int = Field(ge=1)
    speeds_m_s: tuple[float, ...]
    inclines_deg: tuple[float, ...]
    fourier_order: int = Field(ge=1)
    torque_fourier_order: int = Field(ge=1)
    cohort_seed: int | None = None

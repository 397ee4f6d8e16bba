"""The one place that names what crosses a file or a socket: columns, wire messages, MCAP payloads.

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

from typing import Annotated, Any, Final, Literal

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
    TIME_S,
    FOOT_ANGLE,
    SHANK_ANGLE,
    ANKLE_MOMENT,
)
#: Used for training when present (LocoHub has no heel-position standard; a model trained without
#: them ignores heel measurements).
OPTIONAL_TRAINING_COLUMNS: Final = (HEEL_FORWARD, HEEL_UP)

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
    outputs: tuple[bool, bool, bool, bool] = Field(
        default=(True, True, True, True), description="which of foot, shank, heel forward, heel up were trained"
    )
    torque_fourier_order: int = Field(ge=1)
    cohort_seed: int | None = None


# =================================================================================================
# Wire and record messages: REST bodies, websocket messages and MCAP channel payloads.
# Browser and device code follow these; `GET /api/schema` serves their JSON schemas, and the MCAP
# channels' JSON schemas are generated from the same classes.
# =================================================================================================

_CODE = r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,31}$"


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid")


class SubjectCreate(_Strict):
    """A person who walks with a device."""

    code: str = Field(pattern=_CODE, description="pseudonymous code, 1-32 of A-Z a-z 0-9 _ . -")
    leg_length_m: float = Field(ge=0.5, le=1.3)
    mass_kg: float = Field(ge=20.0, le=250.0)
    side: Literal["left", "right"] = "right"
    notes: str = Field(default="", max_length=2000)


class Subject(SubjectCreate):
    id: int
    created_utc: str


#: Bounds of every clinician-adjustable setting: (minimum, maximum, largest change per second).
SETTING_LIMITS: Final[dict[str, tuple[float, float, float]]] = {
    "torque_gain": (0.0, 3.0, 0.5),
    "max_torque_Nm": (0.0, 80.0, 10.0),
    "measurement_noise_scale": (0.1, 10.0, 5.0),
    "process_noise_scale": (0.1, 10.0, 5.0),
}


class SessionSettings(_Strict):
    """Assistance and estimator tuning of one session (seed 000's defaults at 1.0)."""

    torque_gain: float = Field(default=1.0, ge=0.0, le=3.0, description="x the 1/5-scaled biological moment")
    max_torque_Nm: float = Field(default=30.0, ge=0.0, le=80.0, description="hard bound on the command")
    measurement_noise_scale: float = Field(default=1.0, ge=0.1, le=10.0)
    process_noise_scale: float = Field(default=1.0, ge=0.1, le=10.0)
    model: str = Field(default="default", pattern=_CODE, description="name of a model in the model store")


class SettingsChange(_Strict):
    """A requested change of some settings; fields left out keep their value."""

    torque_gain: float | None = Field(default=None, ge=0.0, le=3.0)
    max_torque_Nm: float | None = Field(default=None, ge=0.0, le=80.0)
    measurement_noise_scale: float | None = Field(default=None, ge=0.1, le=10.0)
    process_noise_scale: float | None = Field(default=None, ge=0.1, le=10.0)
    actor: str = Field(default="clinician", max_length=64)
    reason: str = Field(default="", max_length=500)


class ProtocolStep(_Strict):
    speed_m_s: float = Field(ge=0.3, le=2.0)
    incline_deg: float = Field(ge=-15.0, le=15.0)
    strides: int = Field(ge=1, le=2000)


#: Seed 000 III-E treadmill protocol: speeds, then an incline staircase up to +10 deg and down to -10.
TREADMILL_PROTOCOL: Final = (
    (1.2, 0.0, 20), (0.8, 0.0, 20), (1.2, 0.0, 20), (0.8, 0.0, 20),
    (1.0, 2.5, 8), (1.0, 5.0, 8), (1.0, 7.5, 8), (1.0, 10.0, 8), (1.0, 5.0, 8), (1.0, 0.0, 8),
    (1.0, -2.5, 8), (1.0, -5.0, 8), (1.0, -7.5, 8), (1.0, -10.0, 8),
)  # fmt: skip


class SimulatedSource(_Strict):
    """A virtual-cohort subject walking a protocol through simulated sensors, in real time."""

    kind: Literal["simulated"] = "simulated"
    protocol: list[ProtocolStep] = Field(
        default_factory=lambda: [ProtocolStep(speed_m_s=v, incline_deg=r, strides=n) for v, r, n in TREADMILL_PROTOCOL],
        min_length=1,
        max_length=200,
    )
    rate_hz: float = Field(default=200.0, ge=20.0, le=1000.0)
    cohort_subject: int = Field(default=0, ge=0, le=9)
    loop: bool = True
    seed: int = Field(default=7, ge=0)


class ReplaySource(_Strict):
    """A stored trial (recorded, or uploaded MCAP / replay CSV / LocoHub file) played back."""

    kind: Literal["replay"] = "replay"
    trial_id: int = Field(ge=1)
    speed: float = Field(default=1.0, ge=1.0, le=50.0, description="1x real time or faster")
    loop: bool = False


class DeviceSource(_Strict):
    """A live device that connects to ``/ws/devices/{session_id}`` and pushes sensor frames.

    ``rate_hz`` is the device's declared sample rate: the server takes up to ``1.25 x rate_hz``
    frames per second (with a burst of two seconds' worth) and drops the rest, counted and reported to
    the device, so that a flooding device cannot starve the other sessions.
    """

    kind: Literal["device"] = "device"
    rate_hz: float = Field(default=200.0, ge=1.0, le=2000.0, description="declared sample rate (Hz)")


class UploadSource(_Strict):
    """A log uploaded for review (MCAP, replay CSV or LocoHub); its session holds the imported trial."""

    kind: Literal["upload"] = "upload"
    filename: str = Field(max_length=200)


SourceSpec = Annotated[SimulatedSource | ReplaySource | DeviceSource | UploadSource, Field(discriminator="kind")]


class SessionCreate(_Strict):
    subject_id: int = Field(ge=1)
    source: SourceSpec = Field(default_factory=SimulatedSource)
    settings: SessionSettings = Field(default_factory=SessionSettings)
    start: bool = True


#: ``failed``: the session's task stopped on an error (its event says which); it was recorded up to there.
SessionState = Literal["created", "running", "stopped", "failed"]


class Session(BaseModel):
    id: int
    subject_id: int
    source: SourceSpec
    settings: SessionSettings
    state: SessionState
    created_utc: str
    started_utc: str | None = None
    stopped_utc: str | None = None


#: ``recovered``: a crash left the recording unfinished and start-up recovery re-indexed it (the last
#: half second or so may be missing). ``damaged``: it was left unfinished and its file is missing or
#: could not be repaired; a system event of its session says why.
TrialStatus = Literal["recording", "finished", "recovered", "uploaded", "damaged"]


class Trial(BaseModel):
    id: int
    session_id: int
    name: str
    status: TrialStatus
    path: str = Field(description="MCAP file, relative to the data folder")
    started_utc: str
    stopped_utc: str | None = None
    samples: int = 0
    duration_s: float = 0.0


EventKind = Literal["setting", "annotation", "system", "recording"]


class AnnotationCreate(_Strict):
    text: str = Field(min_length=1, max_length=500)
    actor: str = Field(default="clinician", max_length=64)


class Event(BaseModel):
    """A setting change, an annotation or a system event: when, what, before, after, who."""

    id: int
    session_id: int
    t: float = Field(description="session time (s) of the sample at which it took effect")
    wall_utc: str
    kind: EventKind
    text: str
    field: str | None = None
    before: float | str | None = None
    after: float | str | None = None
    actor: str = "system"


class RecordingControl(_Strict):
    action: Literal["start", "stop"]
    name: str = Field(default="", max_length=100)


class UploadCreate(_Strict):
    filename: str = Field(
        min_length=1,
        max_length=200,
        # no folder separators, no control characters (C0, DEL, C1), no line or paragraph separators and
        # no bidirectional controls ("x\u202egpj.csv" displays as "xvsc.jpg")
        pattern=r"^[^/\\\x00-\x1f\x7f-\x9f\u2028\u2029\u200e\u200f\u202a-\u202e\u2066-\u2069]+\.(mcap|csv|parquet)$",
    )
    size: int = Field(ge=1, description="bytes; refused above the server's limit")
    subject_id: int = Field(ge=1)


class Upload(BaseModel):
    id: str
    filename: str
    size: int
    received: int
    chunk_size: int


class RerunRequest(_Strict):
    """A re-run of a recorded trial's sensor frames through the estimators (``POST /api/trials/{id}/rerun``).

    Two modes, by ``settings``:

    * left out or null (the default): **as recorded**. The trial's recorded settings are replayed: those
      in force at its first frame, then each recorded change (``/settings``) from the frame after the one
      it followed, as it applied live; the model is the recorded one. The result reproduces the recorded
      gait states to floating-point round-off: the baseline of "what ran".
    * given: **what if**. These settings, model included, held constant over the whole trial (recorded
      changes are not applied).
    """

    settings: SessionSettings | None = Field(
        default=None, description="null: as recorded (the default); else these settings over the whole trial"
    )


# --- per-sample messages (websocket and MCAP) ----------------------------------------------------

#: Physically plausible range of each sensor channel (units in the name). A value outside it, or a
#: JSON ``NaN`` / ``Infinity``, is treated as missing for that sample, counted and shown in data
#: health (``Health.implausible``); the rest of the frame is used. Angles within +/-180 deg, angular
#: velocities within +/-4000 deg/s (the largest full scale of common MEMS gyros), raw heel positions
#: within +/-3 m of the hip. The estimators state the same bounds (``estimators.pipeline.CHANNEL_LIMITS``).
SENSOR_LIMITS: Final[dict[str, tuple[float, float]]] = {
    "foot_angle_deg": (-180.0, 180.0),
    "foot_vel_dps": (-4000.0, 4000.0),
    "shank_angle_deg": (-180.0, 180.0),
    "shank_vel_dps": (-4000.0, 4000.0),
    "heel_forward_m": (-3.0, 3.0),
    "heel_up_m": (-3.0, 3.0),
    "thigh_angle_deg": (-180.0, 180.0),
}
#: Largest integer a frame may carry (``seq``, ``sent_ns``): a signed 64-bit integer, as MCAP and SQLite.
INT64_MAX: Final = 2**63 - 1


class SensorFrame(_Strict):
    """One sample from a device (``/ws/devices/{id}``) or a source; absent channel = None.

    ``t`` is the device's own clock (s) and must be a finite number: a frame without a usable time is
    refused. Channel values outside :data:`SENSOR_LIMITS` (or NaN / Infinity) are accepted here and
    treated as missing by :meth:`plausible`, which the estimators run on every frame. ``sent_ns`` is
    the device's wall clock at send time (ns since the epoch, optional) for end-to-end latency.
    """

    type: Literal["frame"] = "frame"
    seq: int = Field(ge=0, le=INT64_MAX)
    t: float = Field(allow_inf_nan=False)
    foot_angle_deg: float | None = None
    foot_vel_dps: float | None = None
    shank_angle_deg: float | None = None
    shank_vel_dps: float | None = None
    heel_forward_m: float | None = None
    heel_up_m: float | None = None
    thigh_angle_deg: float | None = Field(default=None, description="for the leg view only")
    heel_strike: bool | None = None
    sent_ns: int | None = Field(default=None, ge=0, le=INT64_MAX)

    def plausible(self) -> tuple[SensorFrame, int]:
        """This frame with implausible channel values set to None, and how many were."""
        bad = {
            name: None
            for name, (lo, hi) in SENSOR_LIMITS.items()
            if (v := getattr(self, name)) is not None and not lo <= v <= hi
        }
        return (self.model_copy(update=bad), len(bad)) if bad else (self, 0)


class GaitState(BaseModel):
    """The estimate at one sample, as streamed to browsers and recorded (``/gait_state``)."""

    seq: int
    t: float
    phase: float
    phase_rate: float
    stride_length_m: float
    incline_deg: float
    torque_Nm: float
    tbe_phase: float
    heel_strike: bool
    backup_reset: bool
    fault: bool = Field(default=False, description="the filters were reset or the torque forced to 0 here")
    foot_angle_deg: float | None
    shank_angle_deg: float | None
    thigh_angle_deg: float | None
    foot_pred_deg: float
    shank_pred_deg: float
    sent_ns: int | None = None
    recv_ns: int = Field(description="server wall clock when the sensor frame arrived (ns)")


class TorqueCommand(BaseModel):
    """Sent back to a live device after each frame, and recorded (``/torque``)."""

    type: Literal["torque"] = "torque"
    seq: int
    t: float
    torque_Nm: float


class StreamBatch(BaseModel):
    """Server -> browser: the gait states since the last batch (decimated as the client asked)."""

    type: Literal["states"] = "states"
    session_id: int
    states: list[GaitState]
    decimation: int = Field(description="every n-th sample is sent")


class Health(BaseModel):
    """Server -> browser, about once a second: data health of the session and of this client."""

    type: Literal["health"] = "health"
    session_id: int
    rate_hz: float
    latency_ms_p50: float | None
    latency_ms_p95: float | None
    samples: int
    dropped_input: int = Field(description="device frames lost, out of order or over the declared rate")
    dropped_client: int = Field(description="batches this client missed because it was slow")
    clients: int
    implausible: int = Field(default=0, description="sensor values outside SENSOR_LIMITS, treated as missing")
    faults: int = Field(default=0, description="filter restarts and resets, and torques forced to 0")
    disk: Literal["ok", "low", "critical"] = Field(default="ok", description="free space for the recording")


class DeviceNotice(BaseModel):
    """Server -> device, instead of a torque command: why a frame was refused or dropped.

    ``kind``: ``invalid`` (the frame failed validation; ``detail`` lists the errors), ``order`` (its
    time does not follow the last frame's), ``rate`` (frames over the declared rate were dropped;
    ``dropped`` counts them since the last notice), ``binary`` (a binary message; frames are JSON text).
    """

    type: Literal["error"] = "error"
    kind: Literal["invalid", "order", "rate", "binary"]
    detail: str | list[dict[str, Any]]
    seq: int | None = None
    dropped: int = 0


class EventMessage(BaseModel):
    type: Literal["event"] = "event"
    event: Event


class SettingsMessage(BaseModel):
    type: Literal["settings"] = "settings"
    session_id: int
    settings: SessionSettings


class Hello(BaseModel):
    type: Literal["hello"] = "hello"
    session: Session
    subject: Subject
    source_rate_hz: float | None


ServerMessage = Annotated[
    Hello | StreamBatch | Health | EventMessage | SettingsMessage | TorqueCommand, Field(discriminator="type")
]


class TimeStamp(BaseModel):
    sec: int
    nsec: int


class KeyValuePair(BaseModel):
    key: str
    value: str


class FoxgloveEvent(BaseModel):
    """Foxglove's ``foxglove.Event`` (start_time, end_time, metadata), so Foxglove lists our events."""

    start_time: TimeStamp
    end_time: TimeStamp
    metadata: list[KeyValuePair] = Field(default_factory=list)


#: MCAP topics and the class whose JSON schema each carries; ``/events`` uses Foxglove's schema name.
MCAP_CHANNELS: Final[dict[str, tuple[str, type[BaseModel]]]] = {
    "/sensor": ("gaitscope.SensorFrame", SensorFrame),
    "/gait_state": ("gaitscope.GaitState", GaitState),
    "/torque": ("gaitscope.TorqueCommand", TorqueCommand),
    "/settings": ("gaitscope.SessionSettings", SessionSettings),
    "/events": ("foxglove.Event", FoxgloveEvent),
}

"""The one place that names what crosses a file or a socket: columns, wire messages, MCAP payloads.

Every column of a LocoHub table gaitscope reads or writes, every column of the replay CSV, and the
metadata of a fitted-model file, every REST body, websocket message and MCAP payload are defined here;
readers, writers, the server and the browser's ``web/wire.js`` derive from these names so that they
cannot drift apart.

LocoHub conventions (jmontp/LocoHub, ``docs/reference/biomechanical_standard.md``): one row per sample,
angles in radians, moments in N m, ``phase_ipsi`` in percent of the ipsilateral gait cycle (0 at heel
strike, 150 points per cycle in phase-indexed files), ``task_info`` a ``key:value,key:value`` string
holding at least ``speed_m_s`` and ``incline_deg``. Sagittal segment angles are viewed from the
subject's right with forward to the right and counter-clockwise positive: thigh and shank from
vertical (positive when the distal end is ahead of the proximal one), foot from horizontal (positive
toes up). With these signs ``foot = shank + ankle_dorsiflexion`` (seed 000: shank = foot - ankle).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING, Annotated, Any, Final, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, create_model, field_validator, model_validator

from gaitscope.estimators import channels, protocol

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
# Both legs, pelvis and feet (schema version 2 of the sensor frame; virtual cohort, docs/cohort.md).
THIGH_ANGLE_CONTRA: Final = "thigh_sagittal_angle_contra_rad"
SHANK_ANGLE_CONTRA: Final = "shank_sagittal_angle_contra_rad"
FOOT_ANGLE_CONTRA: Final = "foot_sagittal_angle_contra_rad"
KNEE_ANGLE_CONTRA: Final = "knee_flexion_angle_contra_rad"
ANKLE_ANGLE_CONTRA: Final = "ankle_dorsiflexion_angle_contra_rad"
PELVIS_ANGLE: Final = "pelvis_sagittal_angle_rad"  # (+) anterior tilt, as LocoHub; thigh = hip - pelvis
VERTICAL_GRF: Final = "vertical_grf_ipsi_N"
VERTICAL_GRF_CONTRA: Final = "vertical_grf_contra_N"
STEP_LENGTH_CONTRA: Final = "step_length_contra_m"  # contralateral step ending in this stride
#: Centre of mass relative to the stance foot (the one that touched down last): forward, lateral (+ to
#: the left, as ``COM_POSITION``), up. Its velocity relative to the stance foot is ``COM_VELOCITY`` (over
#: the belt surface) on the level; on a slope the stance foot moves along it with the belt.
COM_STANCE_POSITION: Final = (
    "com_forward_position_stance_m",
    "com_lateral_position_stance_m",
    "com_vertical_position_stance_m",
)
#: Segments that carry an IMU; ``_contra`` ones are on the contralateral leg.
IMU_SEGMENTS: Final = channels.IMU_SEGMENTS
#: Linear acceleration (gravity not included; forward, up; m/s^2) of each segment's IMU mounting point.
IMU_POINT_ACCELERATION: Final[dict[str, tuple[str, str]]] = {
    seg: (f"imu_{seg}_forward_acceleration_m_s2", f"imu_{seg}_vertical_acceleration_m_s2") for seg in IMU_SEGMENTS
}

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
#: The replay CSV's signal columns: the phase EKF's measurement channels, in its order.
REPLAY_SIGNALS: Final = protocol.SENSOR_CHANNELS
REPLAY_ANGLES: Final = ("foot_angle_deg", "shank_angle_deg")
REPLAY_HEEL_STRIKE: Final = protocol.HEEL_STRIKE
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


#: Largest integer a frame may carry (``seq``, ``sent_ns``): a signed 64-bit integer, as MCAP and SQLite.
INT64_MAX: Final = 2**63 - 1


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
#: Who made a request: the server sets it to the caller (the logged-in user; ``local`` with accounts off)
#: whatever the body says, so that the event log's "who" never comes from the request.
_ACTOR = Field(
    default="local", min_length=1, max_length=64, description="set by the server to the logged-in user; ignored if sent"
)


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


#: Bounds of every clinician-adjustable setting: (minimum, maximum, largest change per second). The one
#: statement of them: ``SessionSettings`` and ``SettingsChange`` take their bounds from here, the
#: session runtime the rate, the command line reads them, and the browser imports them from the
#: generated ``web/wire.js`` (``gaitscope wire``).
SETTING_LIMITS: Final[dict[str, tuple[float, float, float]]] = {
    "torque_gain": (0.0, 3.0, 0.5),
    "max_torque_Nm": (0.0, 80.0, 10.0),
    "measurement_noise_scale": (0.1, 10.0, 5.0),
    "process_noise_scale": (0.1, 10.0, 5.0),
    "intent_gain_boost": (0.0, 0.3, 0.1),
}
#: The name on screen and the unit (as people write it; "" for none) of every field a setting event may change:
#: the settings of :data:`SETTING_LIMITS`, the primary estimator and the models. The one statement of them:
#: the events list, the review's markers, the session summary and its PDF read it (the browser from the
#: generated ``web/wire.js``); an estimator's name on screen is its descriptor's ``label``.
SETTING_NAMES: Final[dict[str, tuple[str, str]]] = {
    "torque_gain": ("Torque gain", "×"),
    "max_torque_Nm": ("Maximum torque", "N·m"),
    "measurement_noise_scale": ("Measurement-noise scale", "×"),
    "process_noise_scale": ("Process-noise scale", "×"),
    "intent_gain_boost": ("Intent gain boost", "fraction of gain"),
    "primary": ("Torque follows", ""),
    "model": ("Gait model", ""),
    "imu_calibration": ("IMU calibration", ""),
}


#: An estimator's name in a session's stack (``phase_ekf``, ``tbe``, ...; ``gaitscope.sessions.registry.ESTIMATORS``).
EstimatorName = Annotated[str, Field(pattern=r"^[a-z][a-z0-9_]{0,31}$")]
#: Least time (s) between two switches of a session's primary estimator, and the time over which the
#: torque command blends from the old primary's to the new one's (so that a switch never steps it).
PRIMARY_SWITCH_INTERVAL_S: Final = 2.0
PRIMARY_BLEND_S: Final = 0.5
#: Least time (s) between two settings changes that can raise the torque on the person (a raise of the torque
#: gain, the maximum torque or the intent boost, or a switch of the primary), each confirmed by the user
#: (``SettingsChange.confirm``; ``gaitscope.sessions.live.torque_rule``). Lowering is never held back.
TORQUE_RAISE_INTERVAL_S: Final = 3.0


def _setting(name: str, default: float | None, description: str | None = None) -> Any:
    """A field bounded by ``SETTING_LIMITS[name]`` (``ge`` its minimum, ``le`` its maximum)."""
    lo, hi, _ = SETTING_LIMITS[name]
    return Field(default=default, ge=lo, le=hi, description=description)


def field_bounds(cls: type[BaseModel], name: str) -> tuple[float, float]:
    """The inclusive bounds (``ge``, ``le``) of a numeric field of a schema class, for code outside pydantic
    (the command line) that must check the same numbers. Raises ``KeyError`` if the field has no such bounds."""
    metadata = cls.model_fields[name].metadata
    found = {k: v for m in metadata for k in ("ge", "le") if (v := getattr(m, k, None)) is not None}
    return float(found["ge"]), float(found["le"])


class SessionSettings(_Strict):
    """Assistance and estimator tuning of one session (seed 000's defaults at 1.0)."""

    torque_gain: float = _setting("torque_gain", 1.0, "x the 1/5-scaled biological moment")
    max_torque_Nm: float = _setting("max_torque_Nm", 30.0, "hard bound on the command")
    measurement_noise_scale: float = _setting("measurement_noise_scale", 1.0)
    process_noise_scale: float = _setting("process_noise_scale", 1.0)
    intent_gain_boost: float = _setting(
        "intent_gain_boost",
        0.0,
        "assistance follows intent (beyond seed 001; 0: off): while the intent estimator says speeding up "
        "(slowing down) the torque gain rises (falls) by up to this fraction, scaled by its confidence",
    )
    model: str = Field(default="default", pattern=_CODE, description="name of a model in the model store")
    primary: EstimatorName = Field(
        default="phase_ekf", description="the estimator of the stack whose phase drives the torque profile"
    )
    estimators: list[EstimatorName] | None = Field(
        default=None,
        max_length=16,
        description="the session's estimator stack, chosen at start and fixed while it runs; "
        "null: every estimator the source's channels allow",
    )
    lsl_outlet: bool = Field(
        default=False,
        description="publish the gait state as a Lab Streaming Layer outlet (type GaitState) while the session "
        "runs, for the lab's recorder; fixed at start",
    )


class SettingsChange(_Strict):
    """A requested change of some settings; fields left out keep their value."""

    torque_gain: float | None = _setting("torque_gain", None)
    max_torque_Nm: float | None = _setting("max_torque_Nm", None)
    measurement_noise_scale: float | None = _setting("measurement_noise_scale", None)
    process_noise_scale: float | None = _setting("process_noise_scale", None)
    intent_gain_boost: float | None = _setting("intent_gain_boost", None)
    primary: EstimatorName | None = Field(
        default=None,
        description=f"switched at most every {PRIMARY_SWITCH_INTERVAL_S:g} s; the torque blends over "
        f"{PRIMARY_BLEND_S:g} s",
    )
    actor: str = _ACTOR
    reason: str = Field(default="", max_length=500)
    confirm: bool = Field(
        default=False,
        description="the user confirmed a change that can raise the torque on the person (a raise of the torque "
        "gain, the maximum torque or the intent boost, or a switch of the primary), having been shown its peak "
        "torque before and after; without it such a change is refused (409, a TorqueRaiseRefused), and at most "
        f"one is made every {TORQUE_RAISE_INTERVAL_S:g} s. Lowering needs no confirmation and is never held back",
    )


class TorqueRaiseRefused(_Strict):
    """The ``detail`` of the 409 to a settings change or undo that can raise the torque on the person and was not
    confirmed (``reason="confirm"``: resend it with ``confirm: true`` once the user agreed to the peaks shown) or
    came too soon after the last such change (``reason="too_soon"``: it may be made ``retry_after_s`` later).
    The peaks are the torque the settings command over a stride at the session's gait state
    (``gaitscope.sessions.peak_torque``), intent boost at its largest."""

    message: str = Field(max_length=1000)
    reason: Literal["confirm", "too_soon"]
    fields: list[str] = Field(description="the settings of the change that can raise the torque")
    peak_before_Nm: float = Field(ge=0.0, description="peak torque over a stride with the settings now")
    peak_after_Nm: float = Field(ge=0.0, description="peak torque over a stride with the change made")
    retry_after_s: float = Field(ge=0.0, description="how long until it may be made (0: now, with confirm)")


class TorqueCheck(_Strict):
    """``POST /api/sessions/{id}/settings/check``: what a settings change would do to the torque, changing nothing,
    for a client to ask its user before it sends the change (which is judged again when sent)."""

    fields: list[str] = Field(description="the settings of the change that can raise the torque ([]: it asks nothing)")
    peak_before_Nm: float = Field(ge=0.0, description="peak torque over a stride with the settings now")
    peak_after_Nm: float = Field(ge=0.0, description="peak torque over a stride with the change made")
    retry_after_s: float = Field(ge=0.0, description="how long until a change that can raise the torque may be made")


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
    seed: int = Field(default=7, ge=0, le=INT64_MAX)


class ReplaySource(_Strict):
    """A stored trial (recorded, or uploaded MCAP / replay CSV / LocoHub file) played back."""

    kind: Literal["replay"] = "replay"
    trial_id: int = Field(ge=1, le=INT64_MAX)
    speed: float = Field(default=1.0, ge=1.0, le=50.0, description="1x real time or faster")
    loop: bool = False


#: The largest sample rate a device may declare (Hz): exoskeleton controllers and lab IMUs sample at
#: 100-500 Hz, 1 kHz at most; beyond that a device's frames are only load on the server.
MAX_DEVICE_RATE_HZ: Final = 1000.0


class DeviceSource(_Strict):
    """A live device that connects to ``/ws/devices/{session_id}`` and pushes sensor frames.

    ``rate_hz`` is the device's declared sample rate, at most :data:`MAX_DEVICE_RATE_HZ`: the server
    takes up to ``1.25 x rate_hz`` frames per second (with a burst of two seconds' worth) and drops the
    rest, counted and reported to the device, so that a flooding device cannot starve the other sessions.
    A session stored before that limit with a higher rate reads as the limit (its row is unchanged).
    """

    kind: Literal["device"] = "device"
    rate_hz: float = Field(
        default=200.0,
        ge=1.0,
        le=MAX_DEVICE_RATE_HZ,
        description=f"declared sample rate (Hz), at most {MAX_DEVICE_RATE_HZ:g}",
    )
    channels: list[str] | None = Field(
        default=None,
        max_length=256,
        description="the SensorFrame channels the device sends: the session's stack is chosen for them, and an "
        "estimator asked for that needs another is refused at start; null: unknown, every estimator may run",
    )

    @field_validator("channels")
    @classmethod
    def _known_channels(cls, v: list[str] | None) -> list[str] | None:
        if v is None:
            return None
        unknown = [c for c in v if c not in CHANNELS]
        if unknown:
            raise ValueError(f"unknown channel {', '.join(unknown[:5])}; see GET /api/schema (SensorFrame)")
        return list(dict.fromkeys(v))

    @field_validator("rate_hz", mode="before")
    @classmethod
    def _stored_rate(cls, v: Any, info: ValidationInfo) -> Any:
        """A stored session (``context={"stored": True}``) that declared more than the limit reads as the limit."""
        stored = isinstance(info.context, dict) and info.context.get("stored")
        if stored and isinstance(v, int | float) and v > MAX_DEVICE_RATE_HZ:
            return MAX_DEVICE_RATE_HZ
        return v


class UploadSource(_Strict):
    """A log uploaded for review (MCAP, replay CSV or LocoHub); its session holds the imported trial."""

    kind: Literal["upload"] = "upload"
    filename: str = Field(max_length=200)
    sha256: str | None = Field(
        default=None, pattern=r"^[0-9a-f]{64}$", description="the file's SHA-256 (null: uploaded before it was kept)"
    )


#: An LSL stream's name, type or source id as a source names it: no quotes (they go into an XPath predicate).
_LSL_TEXT = r"^[^'\"\\]{1,200}$"


class LslSource(_Strict):
    """A Lab Streaming Layer stream (an IMU, EMG or motion capture outlet on the lab's network), resolved by
    ``name`` and/or ``type`` (and ``source_id`` if given) when the session starts
    (:mod:`gaitscope.sessions.live.lsl_source`).

    ``mapping`` gives each stream channel used its SensorFrame channel: by index (``"0"``, ``"1"``, ...) or by
    the label in the stream's XML description. Null: the mapping saved for the stream's rig (its name, type,
    channel count and source id), which a session given one saves. Frame time is the sample's LSL time on this
    machine's clock (``time_correction()`` added), from 0 at the first sample.
    """

    kind: Literal["lsl"] = "lsl"
    name: str | None = Field(default=None, pattern=_LSL_TEXT, description="the stream's name (null: any)")
    type: str | None = Field(default=None, pattern=_LSL_TEXT, description="the stream's type, e.g. IMU (null: any)")
    source_id: str | None = Field(default=None, pattern=_LSL_TEXT, description="the stream's source id (null: any)")
    mapping: dict[str, str] | None = Field(
        default=None,
        min_length=1,
        max_length=256,
        description="stream channel (index from 0, or label) -> SensorFrame channel; null: the one saved for the rig",
    )
    resolve_timeout_s: float = Field(default=2.0, ge=0.1, le=30.0, description="how long to look for the stream")
    quiet_s: float = Field(
        default=2.0, ge=0.1, le=60.0, description="no sample for this long: the stream is quiet (the session holds)"
    )

    @model_validator(mode="after")
    def _named(self) -> LslSource:
        if self.name is None and self.type is None:
            raise ValueError("an LSL source needs the stream's name or type (or both)")
        return self

    @field_validator("mapping")
    @classmethod
    def _known_targets(cls, v: dict[str, str] | None) -> dict[str, str] | None:
        if v is None:
            return None
        unknown = [c for c in v.values() if c not in CHANNELS]
        if unknown:
            raise ValueError(f"unknown channel {', '.join(unknown[:5])}; see GET /api/schema (SensorFrame)")
        twice = sorted({c for c in v.values() if list(v.values()).count(c) > 1})
        if twice:
            raise ValueError(f"channel {', '.join(twice[:5])} mapped from more than one stream channel")
        if any(not k or len(k) > 200 for k in v):
            raise ValueError("a stream channel is an index or a label of 1 to 200 characters")
        return v


SourceSpec = Annotated[
    SimulatedSource | ReplaySource | DeviceSource | LslSource | UploadSource, Field(discriminator="kind")
]


class SessionCreate(_Strict):
    subject_id: int = Field(ge=1, le=INT64_MAX)
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
    node: str | None = Field(
        default=None, description="the server process that runs (or ran) it: several may share one database"
    )


class ClusterNode(BaseModel):
    """A gaitscope process sharing this database (``GET /api/cluster/nodes``; ``sessions/cluster``)."""

    name: str = Field(description="its node name (GAITSCOPE_NODE)")
    address: str = Field(description="host:port the proxy reaches it at")
    state: Literal["up", "gone"] = Field(description="gone: its beat stopped and another node took its sessions over")
    seen_utc: str = Field(description="its last beat, ISO-8601 UTC")
    running: int = Field(ge=0, description="sessions it runs")
    live: bool = Field(description="up, with a beat younger than the timeout")
    this: bool = Field(description="the node that answered")


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


#: ``intent``: the speed-change intent estimator detected a change (:mod:`gaitscope.sessions.live.runtime`), one event
#: per onset of speeding up or slowing down.
EventKind = Literal["setting", "annotation", "system", "recording", "intent"]


class AnnotationCreate(_Strict):
    text: str = Field(min_length=1, max_length=500)
    actor: str = _ACTOR


class Event(BaseModel):
    """A setting change, an annotation, a system event or a detected speed-change intent: when, what,
    before, after, who."""

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
        # the extension in any case ("x.CSV"), spelled out: the browser's RegExp has no inline (?i)
        pattern=r"^[^/\\\x00-\x1f\x7f-\x9f\u2028\u2029\u200e\u200f\u202a-\u202e\u2066-\u2069]+"
        r"\.([Mm][Cc][Aa][Pp]|[Cc][Ss][Vv]|[Pp][Aa][Rr][Qq][Uu][Ee][Tt]|[Cc]3[Dd])$",
    )
    size: int = Field(ge=1, le=INT64_MAX, description="bytes; refused above the server's limit")
    subject_id: int = Field(ge=1, le=INT64_MAX)


class Upload(BaseModel):
    id: str
    filename: str
    size: int
    received: int
    chunk_size: int


class RegisteredEstimator(BaseModel):
    """A registered estimator as ``GET /api/estimators`` describes it (its descriptor in
    ``gaitscope.sessions.registry.DESCRIPTORS``), for choosing a session's stack (``SessionSettings.estimators``
    and ``primary``), with what it costs on this server. Named so, not ``EstimatorInfo``: that is ``wire.js``'s
    type of its ``ESTIMATORS`` table."""

    name: EstimatorName = Field(description="its machine name, as SessionSettings.estimators and primary name it")
    label: str = Field(description="its name on screen")
    purpose: str = Field(description="what it is for, in one line")
    paper: str | None = Field(description="the paper it implements (its seed); null: none, gaitscope's own")
    inputs: list[str] = Field(description="the channels it requires (SensorFrame field names)")
    inputs_any: list[str] = Field(description="it needs at least one of these (empty: no such rule)")
    optional_inputs: list[str] = Field(description="channels it uses when the source sends them")
    phase: bool = Field(description="it estimates a phase (of the gait cycle or of stance): the torque may follow it")
    opt_in: bool = Field(description="a session runs it only when named: the default stack leaves it out")
    derives: bool = Field(
        description="a front end deriving channels: the default stack leaves it out when the source sends them"
    )
    cost_us: float | None = Field(
        description="its median time per sample on this server (microseconds), measured at start-up over a "
        "synthetic walk; null: not measured (the model cannot build it)"
    )


class EstimatorFeed(BaseModel):
    """How a log's channels feed one registered estimator (the registry's rule,
    :func:`gaitscope.sessions.registry.feeds`): an import's report and its preview."""

    name: str
    label: str
    feedable: bool = Field(description="its inputs are in the log, or derived from it by estimators before it")
    ran: bool = Field(description="the import ran it (opt-in estimators run only in a re-run that names them)")
    missing: list[str] = Field(default_factory=list, description="what it lacks ('a or b': either)")
    derived: dict[str, list[str]] = Field(
        default_factory=dict, description="inputs the log lacks that these estimators derive"
    )


class ImportReport(BaseModel):
    """What an import read from a file and what it can feed, in the user's terms."""

    format: str = Field(description="mcap, replay_csv, locohub_csv, parquet, c3d, foreign_mcap")
    channels: list[str] = Field(description="the channels the file sends (SensorFrame field names)")
    derived: list[str] = Field(
        default_factory=list, description="channels computed from others (velocities from their angles)"
    )
    ignored: list[str] = Field(default_factory=list, description="the file's columns or fields not read")
    estimators: list[EstimatorFeed] = Field(default_factory=list)
    warnings: list[str] = Field(default_factory=list, description="implausible values, named in the user's terms")


MappingKind = Literal["mcap", "c3d", "lsl"]


class ImportOptions(_Strict):
    """How to read an upload (``POST /api/uploads/{id}/preview`` and ``/finish``): the channel mapping of a file
    whose fields are not named as gaitscope's channels."""

    mapping: str | None = Field(
        default=None,
        max_length=200_000,
        description="JSON: for an MCAP recording of another tool, its fields' channels "
        "(gaitscope.sessions.formats.foreign_mcap.ChannelMapping); for a C3D file, its marker set "
        "(gaitscope.sessions.formats.c3d.C3DMapping). Null: the mapping saved for the file's rig, else the "
        "suggested one (Plug-in Gait for C3D)",
    )
    allow_other_rig: bool = Field(default=False, description="use a mapping saved for another rig")


class SourceField(BaseModel):
    """A field of a file that a mapping can give a channel: a topic's field of an MCAP recording of another tool
    (``topic``, ``path``), or a C3D marker or analog channel (``topic`` ``marker`` or ``analog``)."""

    topic: str
    path: str
    kind: str = Field(description="number, bool, marker or analog")
    count: int | None = None
    rate_hz: float | None = None
    min: float | None = None
    max: float | None = None
    channel: str | None = Field(
        default=None, description="the channel the mapping in use gives it, or a C3D marker's role (null: none)"
    )


class PreviewChannel(BaseModel):
    """One channel of an import preview: where it comes from, its unit, what its values look like."""

    channel: str
    unit: str
    source: str = Field(description="the file's column, field or marker set it comes from")
    count: int
    min: float | None
    max: float | None
    plausible: tuple[float, float] | None = Field(description="its plausible range (SENSOR_LIMITS); null: a flag")
    outside: int = Field(description="values outside the plausible range (treated as missing)")


class ImportPreview(BaseModel):
    """What an import would read from an upload, from its first :data:`PREVIEW_S` seconds, before anything is
    stored: the channels and their values (a small plot of each), what they feed, what looks wrong, and the
    mapping in use (editable) for a file that needs one."""

    filename: str
    format: str
    previewed_s: float = Field(description="seconds of the file read for the preview")
    complete: bool = Field(description="the preview read the whole file")
    report: ImportReport
    channels: list[PreviewChannel]
    t: list[float] = Field(description="times (s) of the plotted samples")
    series: dict[str, list[float | None]] = Field(description="each channel at the times t")
    mapping_kind: MappingKind | None = None
    mapping: str | None = Field(default=None, description="the mapping in use, as JSON (null: none needed)")
    mapping_source: Literal["given", "saved", "suggested"] | None = None
    rig: str | None = Field(default=None, description="the file's rig signature (a saved mapping's key)")
    fields: list[SourceField] = Field(default_factory=list)
    problem: str | None = Field(default=None, description="why the import would be refused (null: it would not)")


#: Seconds of an upload an import preview reads.
PREVIEW_S: Final = 60.0
#: Samples per channel an import preview plots.
PREVIEW_POINTS: Final = 400


class SavedMapping(BaseModel):
    """A channel mapping saved for a rig (the next file of the same rig maps itself)."""

    rig: str
    kind: MappingKind
    mapping: str
    actor: str
    updated_utc: str


class ImportedTrial(Trial):
    """A trial an upload made, with what the import read (``POST /api/uploads/{id}/finish``)."""

    report: ImportReport


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
    estimators: list[EstimatorName] | None = Field(
        default=None,
        max_length=16,
        description="the estimators to re-run (their outputs come back as '<name>.<output>' columns); "
        "null: the trial's recorded stack",
    )
    personalization_id: int | None = Field(
        default=None,
        ge=1,
        le=INT64_MAX,
        description="the subject's personalization whose fingerprint fp_ls runs (compare before promoting); "
        "null: the subject's active one, if any",
    )


#: Most components a gait fingerprint has (seed 004 keeps 3; a map is at most n_subjects - 1 wide).
MAX_FINGERPRINT: Final = 16
FingerprintValue = Annotated[float, Field(ge=-1000.0, le=1000.0, allow_inf_nan=False)]
PersonalizationState = Literal["candidate", "active", "retired"]


class CalibrationRequest(_Strict):
    """Fit a subject's gait fingerprint from a recorded or uploaded trial of theirs (``POST
    /api/subjects/{id}/fingerprints``): strides between heel strikes, thigh angle against phase and stride
    length (belt speed x stride time when the trial records the belt, else the recorded estimate)."""

    trial_id: int = Field(ge=1, le=INT64_MAX)
    model: str = Field(default="default", pattern=_CODE)
    actor: str = _ACTOR
    note: str = Field(default="", max_length=500)


#: The buttressed Kalman filter's tunings a subject may have (seed 001): ``uninjured`` (eq. 1's step-length
#: model) or ``isci`` (with the hip-motor current model of eq. 14, for incomplete spinal cord injury).
IntentVariant = Literal["uninjured", "isci"]


class IntentModelRequest(_Strict):
    """Set a subject's speed-change intent model (``PUT /api/subjects/{id}/intent-model``): the variant, and
    the trial of theirs its step-length model (and, for ``isci``, its hip-current model) is fitted on; without
    a trial, the variant's default (the cohort's kappa for ``uninjured``, seed 001's iSCI tuning for ``isci``).
    It runs from the subject's next session on; a running session keeps what it started with."""

    variant: IntentVariant = "uninjured"
    trial_id: int | None = Field(default=None, ge=1, le=INT64_MAX)
    note: str = Field(default="", max_length=500)


class IntentModel(BaseModel):
    """A subject's speed-change intent model: what their intent filter runs (``estimators.intent.BKFConfig``)
    and where it came from."""

    subject_id: int
    variant: IntentVariant
    kappa: tuple[float, float, float] = Field(description="eq. 1: step length = [v, v_d - v, leg length] kappa")
    alpha: tuple[float, float] | None = Field(description="eq. 14 (iSCI): RMS hip current = [v, v_d - v] alpha (A)")
    source: str = Field(description="the default it is, or the trial it was fitted on")
    source_trial_id: int | None = None
    steps: int = Field(ge=0, description="steps the fit used (0: a default)")
    step_rmse_m: float | None = Field(description="eq. 1's RMSE on those steps (m)")
    actor: str
    updated_utc: str
    note: str = ""


class PersonalizationChange(_Strict):
    """Promote a personalization or roll back to the one before (``.../promote``, ``.../rollback``)."""

    actor: str = _ACTOR
    reason: str = Field(default="", max_length=500)
    confirm: bool = Field(
        default=False,
        description="the user confirmed the change of what drives the torque: required (else 409) while a running "
        "session of the subject has its torque follow the personalized filter (fp_ls), which takes the change live",
    )


class Personalization(BaseModel):
    """One version of a subject's personalized gait model: a fingerprint in a model's map (seed 004).

    ``candidate`` after a calibration or an import, ``active`` once promoted (at most one per subject and
    model: the one live sessions and review use for ``fp_ls``), ``retired`` when another was promoted.
    """

    id: int
    subject_id: int
    version: int = Field(description="1, 2, ... per subject")
    model: str = Field(description="the model whose fingerprint map this fingerprint belongs to")
    fingerprint: list[FingerprintValue] = Field(max_length=MAX_FINGERPRINT, description="g_1..g_k, deg RMS each")
    fit_rmse_avg_deg: float = Field(description="thigh-angle RMSE of the average model on the calibration walk")
    fit_rmse_personal_deg: float = Field(description="the same with this fingerprint")
    source_trial_id: int | None = Field(description="the calibration trial; null: imported")
    strides_used: int
    strides_excluded: int
    seconds_used: float
    excluded: dict[str, int] = Field(description="strides left out, by reason")
    stride_length_source: str = Field(description="'belt speed' or the estimator whose stride length was used")
    state: PersonalizationState
    created_utc: str
    created_by: str
    promoted_utc: str | None = None
    promoted_by: str | None = None
    retired_utc: str | None = Field(default=None, description="when another was promoted or it was rolled back")
    retired_by: str | None = None
    note: str = ""


class CohortPoint(BaseModel):
    """A training subject's least-squares fingerprint in the model's map (the fingerprint plot's cloud)."""

    code: str
    fingerprint: list[float]


class Fingerprints(BaseModel):
    """A subject's personalized models (``GET /api/subjects/{id}/fingerprints``)."""

    subject_id: int
    model: str
    components: int = Field(description="fingerprint components of the model's map (0: it has none)")
    explained: list[float] = Field(description="cumulative variance share per component of the map")
    active: Personalization | None
    versions: list[Personalization] = Field(description="newest first")
    cohort: list[CohortPoint]


class PersonalizationExport(_Strict):
    """A personalization moved between machines (``.../export``, ``.../import``): the fingerprint with the
    model it belongs to, identified by the model's training-data hash so a map that differs is refused."""

    format: Literal["gaitscope-personalization"] = "gaitscope-personalization"
    version: Literal[1] = 1
    subject_code: str = Field(pattern=_CODE)
    model: str = Field(pattern=_CODE)
    model_sha256: str = Field(pattern=r"^[0-9a-f]{64}$")
    fingerprint: list[FingerprintValue] = Field(min_length=1, max_length=MAX_FINGERPRINT)
    fit_rmse_avg_deg: float = Field(ge=0, allow_inf_nan=False)
    fit_rmse_personal_deg: float = Field(ge=0, allow_inf_nan=False)
    strides_used: int = Field(ge=0, le=INT64_MAX)
    seconds_used: float = Field(ge=0, allow_inf_nan=False)
    created_utc: str = Field(max_length=40)
    note: str = Field(default="", max_length=500)


#: Shortest and longest standing period of an IMU mounting calibration, and its default (s).
IMU_CALIBRATION_S: Final = (2.0, 30.0, 5.0)
ImuCalibrationState = Literal["idle", "collecting", "done", "refused"]


class ImuCalibrationRequest(_Strict):
    """Start a standing calibration of a live session's IMUs (``POST /api/sessions/{id}/imu-calibration``):
    the subject stands still, upright, for ``duration_s`` of session time."""

    duration_s: float = Field(
        default=IMU_CALIBRATION_S[2], ge=IMU_CALIBRATION_S[0], le=IMU_CALIBRATION_S[1], allow_inf_nan=False
    )
    actor: str = _ACTOR
    note: str = Field(default="", max_length=500, description="the posture, or anything worth keeping with it")


class ImuSensorCalibration(_Strict):
    """One sensor's result (``gaitscope.estimators.imu_calibration.SensorCalibration``): the offsets its front end
    ``imu_<segment>`` takes, or why it was refused."""

    segment: str = Field(pattern=r"^[a-z_]{1,32}$", description="foot, shank, thigh, foot_contra, ...")
    ok: bool
    reason: str = Field(default="", max_length=500, description="empty when accepted")
    pitch_offset_deg: float = Field(ge=-180.0, le=180.0, allow_inf_nan=False)
    gyro_bias_dps: tuple[float, float, float] = Field(description="x, y, z (deg/s)")
    gyro_motion_dps: float | None = Field(description="largest gyro deviation from its mean (null: too few samples)")
    accel_sd: float | None = Field(description="largest per-axis accelerometer sd (m/s^2)")


class ImuCalibration(_Strict):
    """An IMU mounting calibration of a subject in a session (also the MCAP ``/imu_calibration`` payload).
    ``ok``: every sensor with data was accepted (stored; the subject's latest is their current one)."""

    id: int | None = Field(default=None, description="null: refused, not stored")
    subject_id: int
    session_id: int
    trial_id: int | None = None
    duration_s: float = Field(ge=0, allow_inf_nan=False)
    ok: bool
    reason: str = Field(default="", max_length=2000, description="refused: each sensor and why")
    sensors: list[ImuSensorCalibration] = Field(max_length=16)
    created_utc: str = Field(default="", max_length=40)
    created_by: str = Field(default="clinician", max_length=64)
    note: str = Field(default="", max_length=500)


class ImuCalibrationStatus(BaseModel):
    """A live session's IMU calibration (``GET /api/sessions/{id}/imu-calibration``)."""

    session_id: int
    state: ImuCalibrationState
    progress: float = Field(ge=0.0, le=1.0, description="share of the standing period collected")
    duration_s: float = Field(description="the period asked for (0: none yet)")
    segments: list[str] = Field(description="the sensors this session can calibrate (its imu_* front ends)")
    result: ImuCalibration | None = Field(description="the last calibration's outcome (done or refused)")
    applied: ImuCalibration | None = Field(description="what the front ends run now (this session's or the subject's)")


# --- seed 003's GP-EKF learning the wearer (issue #11; gaitscope.sessions.live.gp_learning) -------------------------

#: The joints of the GP-EKF's observation models (``gaitscope.estimators.gp_ekf``), in its order.
GP_JOINTS: Final = ("hip", "knee", "ankle")
#: Stance-phase points (0..1) of the learned means and bands in a :class:`GPLearningState`.
GP_BAND_POINTS: Final = 51
#: What a ``/gp_models`` record says happened: ``trained`` (a fit came back and the filter accepted it: it
#: is installed at the next heel strike), ``refused`` (a fit the filter refused: the current version is
#: kept), ``failed`` (the fit raised), ``installed`` (a version took over at a heel strike), ``kept`` (at a
#: recording's start: a version the filter keeps from before it), ``frozen``, ``unfrozen``, ``rollback``
#: (the clinician's controls).
GPModelWhat = Literal["trained", "refused", "failed", "installed", "kept", "frozen", "unfrozen", "rollback"]


class GPArray(_Strict):
    """One array of a GP model set (``estimators.gp_models.GPModelSet.to_arrays``): its shape and its values in
    C order (JSON numbers read back to the same float64)."""

    shape: list[int] = Field(max_length=4)
    values: list[float]


class GPModelRecord(_Strict):
    """One happening of the GP-EKF's learning (the MCAP ``/gp_models`` payload), logged at the session time
    of the sample it followed (an install: of its heel strike). A review re-run installs the recorded
    versions (``trained`` and ``kept`` carry their arrays) at the recorded ``installed`` times."""

    t: float = Field(description="session time (s)")
    what: GPModelWhat
    version: int | None = Field(default=None, ge=0, le=INT64_MAX, description="the model version concerned")
    steps: tuple[int, int] | None = Field(default=None, description="training window: first and last stance")
    span_s: tuple[float, float] | None = Field(default=None, description="training window: first and last time")
    rmse: dict[str, float | None] = Field(
        default_factory=dict,
        description="held-out RMSE per channel ('hip angle': deg, 'hip velocity': deg/s; null: no sample)",
    )
    fit_s: float | None = Field(default=None, description="wall time the fit took (s)")
    step: int | None = Field(default=None, description="installed: completed stances before its heel strike")
    current: bool = Field(default=False, description="kept: the version in force at the recording's start")
    reason: str = Field(default="", max_length=2000, description="refused, failed: why; rollback: the note")
    actor: str = Field(default="system", max_length=64)
    arrays: dict[str, GPArray] | None = Field(default=None, description="trained, refused, kept: the model set")


class EstimationState(_Strict):
    """The estimation state at a trial's start (the MCAP ``/estimation_state`` payload, one per trial, at the
    session time of the last sample before its first frame): the whole frame estimator, which a review re-run
    restores to reproduce what ran from the first frame (:mod:`gaitscope.sessions.formats.stack_state`)."""

    t: float = Field(description="session time (s) of the state: the last sample before the trial's first frame")
    encoding: str = Field(max_length=64, description="how data is encoded (stack_state.ENCODING)")
    estimators: list[str] = Field(max_length=64, description="the stack it is the state of, in run order")
    sha256: str = Field(pattern="^[0-9a-f]{64}$", description="SHA-256 of the decoded data")
    data: str = Field(description="the state, base64")


class GPModelInfo(BaseModel):
    """A model version the GP-EKF keeps (one a rollback can reinstall)."""

    version: int
    population: bool = Field(description="the first model, fitted to the virtual cohort, not to this wearer")
    steps: tuple[int, int] | None = Field(description="its training window's first and last stance (null: population)")
    span_s: tuple[float, float] | None = Field(description="its training window's time span (s; null: population)")
    rmse_deg: dict[str, float | None] = Field(description="held-out angle RMSE by joint (deg)")
    rmse_dps: dict[str, float | None] = Field(description="held-out velocity RMSE by joint (deg/s)")
    installed_t: list[float] = Field(description="session times (s) of its installs (heel strikes) still kept")


class GPBand(BaseModel):
    """A version's learned joint angles over stance phase (:attr:`GPLearningState.phase`): the GP mean and its
    band of +-2 predictive sd (the GP's variance with its noise: the spread of a measured angle), by joint."""

    version: int
    mean_deg: dict[str, list[float]]
    lower_deg: dict[str, list[float]] = Field(description="mean - 2 sd")
    upper_deg: dict[str, list[float]] = Field(description="mean + 2 sd")


class GPPendingFit(BaseModel):
    """A fit under way in the background."""

    version: int
    steps: tuple[int, int]
    span_s: tuple[float, float]
    running_s: float = Field(description="wall time since it was submitted (s)")


class GPLearningState(BaseModel):
    """A running session's GP-EKF learning (``GET /api/sessions/{id}/gp-learning``)."""

    session_id: int
    version: int = Field(description="the version installed now")
    waiting: int | None = Field(description="the version installed at the next heel strike (null: none)")
    rollback: bool = Field(description="the waiting version is a rollback")
    frozen: bool = Field(description="learning is frozen: no fit, no install but a rollback")
    pending: GPPendingFit | None
    queued_s: float | None = Field(
        default=None,
        description="a training window is ready and has waited this long (s) for the fitting worker, which the "
        "server's learning sessions share within its duty budget (null: none waiting)",
    )
    versions: list[GPModelInfo] = Field(description="the versions kept, by version (rollback targets)")
    last: str = Field(description="the last learning event's text ('' none yet)")
    phase: list[float] = Field(description="stance phase of the band's points, 0..1")
    current: GPBand = Field(description="the installed version's band")
    requested: GPBand | None = Field(description="the band of the version asked for (?version=), if any")


class GPLearningControl(_Strict):
    """A clinician's control of a running session's GP-EKF learning (``POST /api/sessions/{id}/gp-learning``):
    ``freeze`` (no more fits or installs), ``unfreeze``, or ``rollback`` to a kept ``version`` (installed at the
    next heel strike, also while frozen)."""

    action: Literal["freeze", "unfreeze", "rollback"]
    version: int | None = Field(default=None, ge=0, le=INT64_MAX, description="rollback: the kept version")
    actor: str = _ACTOR
    reason: str = Field(default="", max_length=500)

    @model_validator(mode="after")
    def _version_with_rollback(self) -> GPLearningControl:
        if (self.version is None) == (self.action == "rollback"):
            raise ValueError("a rollback names the version to reinstall; freeze and unfreeze take none")
        return self


class RerunChoices(BaseModel):
    """Which estimators a re-run of a recorded trial can run (``GET /api/trials/{id}/estimators``): what a
    review's picker offers. Any subset of ``runnable`` may be asked for (``RerunRequest.estimators``); the
    server stays the judge (a subset without the estimator that derives a channel another needs is 422).
    """

    recorded: list[str] | None = Field(
        description="the stack the trial was recorded with, in the order it ran; null: not recorded "
        "(a log from another tool)"
    )
    default: list[str] = Field(
        description="what a re-run without 'estimators' runs: the recorded stack, else every estimator the "
        "trial's channels allow but the opt-in ones"
    )
    runnable: list[EstimatorName] = Field(
        description="the registered estimators the trial's channels can feed (the recorded ones ran), in the "
        "order a stack runs them"
    )
    derived: dict[EstimatorName, dict[str, list[EstimatorName]]] = Field(
        default_factory=dict,
        description="of a runnable estimator, each channel it requires that the trial lacks, with the "
        "estimators before it that derive it (one of them must run too)",
    )
    refused: dict[EstimatorName, str] = Field(
        default_factory=dict, description="the other registered estimators, each with why it cannot run"
    )


class IntentSeries(BaseModel):
    """A trial's speed-change intent over time (``GET /api/trials/{id}/intent``): the recorded outputs of
    its ``intent`` estimator (seed 001), decimated as a trial's series, or why there are none."""

    recorded: bool = Field(description="the trial records the intent estimator's outputs (its stack ran it)")
    missing: list[str] = Field(
        default_factory=list,
        description="when not recorded: the channels the intent estimator requires that the trial lacks (empty: "
        "it can run, a re-run shows it)",
    )
    series: dict[str, list[float | None]] = Field(
        default_factory=dict,
        description="'t' (session time, s) and each output of the estimator (desired_speed_m_s, speed_m_s, ...), "
        "row for row; empty when not recorded",
    )


class ModelInfo(BaseModel):
    """A model in the model store (``GET /api/models``)."""

    name: str
    provenance: ModelProvenance


class ViewerFocus(BaseModel):
    """Which running session the leg view follows (``POST /api/viewer/focus``)."""

    session_id: int = Field(ge=1, le=INT64_MAX)


class ViewerShow(BaseModel):
    """Pose the leg view at time ``t`` (s) of a trial: the review page's cursor (``POST /api/viewer/show``)."""

    trial_id: int = Field(ge=1, le=INT64_MAX)
    t: float = Field(ge=-1e9, le=1e9, allow_inf_nan=False, description="session time (s), finite, within 30 years")


# --- per-sample messages (websocket and MCAP) ----------------------------------------------------

#: One sensor channel: its ``unit`` (``"bool"`` for a flag), what it is, its ``group`` and plausible range
#: (``limits``, None for a flag); a row of the channel table :mod:`gaitscope.estimators.channels`.
Channel = channels.Channel
#: Every sensor channel a :class:`SensorFrame` may carry, by name, in field order: unit, meaning, group,
#: plausible range. The channel table itself (:data:`gaitscope.estimators.channels.CHANNELS`): the
#: :class:`SensorFrame` fields are made from it, and estimators declare the channels they need by its names
#: (:func:`missing_channels`).
CHANNELS: Final[dict[str, Channel]] = channels.CHANNELS
#: Physically plausible range of each numeric sensor channel (units in the name), from the channel table
#: (:data:`gaitscope.estimators.channels.LIMITS`, where the ranges are explained). A value outside it, or a
#: JSON ``NaN`` / ``Infinity``, is treated as missing for that sample, counted and shown in data health
#: (``Health.implausible``); the rest of the frame is used.
SENSOR_LIMITS: Final[dict[str, tuple[float, float]]] = channels.LIMITS
_LIMIT_ROWS: Final = tuple((name, lo, hi) for name, (lo, hi) in SENSOR_LIMITS.items())
#: Below this many given fields :meth:`SensorFrame.plausible` checks only those (faster for sparse frames).
_FEW_CHANNELS: Final = 24
#: Version of :class:`SensorFrame` this code writes. 1: the frame before the channel registry (seven
#: ipsilateral channels, no ``version`` field); 2: every channel of :data:`CHANNELS`.
SENSOR_FRAME_VERSION: Final = 2


def _field(ch: Channel) -> tuple[Any, Any]:
    """The :class:`SensorFrame` field of a channel: optional (None when the device does not measure it),
    ``bool`` for a flag, else ``float``; its description the channel's, with its unit."""
    if ch.unit == "bool":
        return bool | None, Field(default=None, description=ch.description)
    return float | None, Field(default=None, description=f"{ch.description} ({ch.unit})")


def missing_channels(required: Iterable[str], available: SensorFrame | Iterable[str]) -> list[str]:
    """The channels of ``required`` that ``available`` lacks, in the order asked.

    ``available`` is a frame (its channels that hold a value) or the channel names a source provides.

    Raises:
        KeyError: a name in ``required`` is not a channel of :data:`CHANNELS` (a typo must not pass as
            "missing").
    """
    if isinstance(available, SensorFrame):
        have = {n for n in CHANNELS if getattr(available, n) is not None}
    else:
        have = set(available)
    out = []
    for name in required:
        if name not in CHANNELS:
            raise KeyError(f"unknown sensor channel {name!r}")
        if name not in have:
            out.append(name)
    return out


class _FrameHead(_Strict):
    """The fields of :class:`SensorFrame` before its channels."""

    type: Literal["frame"] = "frame"
    version: Literal[1, 2] = Field(default=SENSOR_FRAME_VERSION, description="schema version; 1 is upgraded on read")
    seq: int = Field(ge=0, le=INT64_MAX)
    t: float = Field(allow_inf_nan=False)

    @field_validator("version")
    @classmethod
    def _upgrade(cls, version: int) -> int:
        """Version 1 frames read as version 2: the version 1 channels kept their names, units and meanings,
        so nothing else changes (an upgrade that renames or rescales a channel goes here)."""
        return SENSOR_FRAME_VERSION


if TYPE_CHECKING:

    class _FrameChannels(_FrameHead):
        """What the type checker sees of the channel fields, which are made at run time from the channel
        table (below): any channel, a number or a flag, None when absent."""

        def __getattr__(self, name: str) -> float | bool | None: ...

else:
    #: :class:`_FrameHead` and one optional field per channel of the table, in its order.
    _FrameChannels = create_model(
        "_FrameChannels", __base__=_FrameHead, __module__=__name__, **{n: _field(c) for n, c in CHANNELS.items()}
    )


# The channel fields come from the channel table (:mod:`gaitscope.estimators.channels`), one per channel in
# its order: ``float | None``, ``bool | None`` for a flag, described by the table (the docstring below is
# the wire's description of the message, unchanged by the table).
class SensorFrame(_FrameChannels):
    """One sample from a device (``/ws/devices/{id}``) or a source; absent channel = None.

    Every channel of :data:`CHANNELS` is optional; units and sign conventions are in each field's
    description (and the registry). ``t`` is the device's own clock (s) and must be a finite number: a
    frame without a usable time is refused. Channel values outside :data:`SENSOR_LIMITS` (or NaN /
    Infinity) are accepted here and treated as missing by :meth:`plausible`, which the estimators run on
    every frame. ``sent_ns`` is the device's wall clock at send time (ns since the epoch, optional) for
    end-to-end latency.

    Versions: a frame without ``version`` is read as the current one. Version 1 frames (recordings,
    replay files and device clients from before version 2, whose channels keep their names, units and
    meanings in version 2) are accepted and upgraded on read: the frame read says ``version=2``.
    """

    sent_ns: int | None = Field(default=None, ge=0, le=INT64_MAX)

    if TYPE_CHECKING:  # the fields the type checker sees do not hold the channels: any keyword is taken

        def __init__(self, **data: Any) -> None: ...

    def plausible(self) -> tuple[SensorFrame, int]:
        """This frame with implausible channel values set to None, and how many were."""
        values, given = self.__dict__, self.model_fields_set
        if len(given) < _FEW_CHANNELS:  # a sparse frame: look only at the fields it was given
            bad = {
                name: None
                for name in given
                if (lim := SENSOR_LIMITS.get(name)) is not None
                and (v := values[name]) is not None
                and not lim[0] <= v <= lim[1]
            }
        else:
            bad = {name: None for name, lo, hi in _LIMIT_ROWS if (v := values[name]) is not None and not lo <= v <= hi}
        return (self.model_copy(update=bad), len(bad)) if bad else (self, 0)


def _longest_frame_bytes() -> int:
    """Bytes of the longest frame of every field of :class:`SensorFrame`: each value as long as a JSON
    number gets (``-1.2345678901234567e-308``; booleans and ``"frame"`` are shorter), a space after each
    separator (about 4 kB)."""
    number = "-1.2345678901234567e-308"
    return len("{" + ", ".join(f'"{name}": {number}' for name in SensorFrame.model_fields) + "}")


#: Largest device frame the server parses, in characters of its JSON text (bytes: a frame is ASCII): four
#: times the longest frame of every channel (:func:`_longest_frame_bytes`), room for indentation and for
#: channels to come, rounded up to KiB (16 KiB). A longer frame is refused unparsed (a ``too_large``
#: :class:`DeviceNotice`); the websocket itself refuses a message over the server's ``ws_max_kb`` before
#: it is read whole.
MAX_FRAME_BYTES: Final = -(-4 * _longest_frame_bytes() // 1024) * 1024
#: Most keys a frame may have: one per field of :class:`SensorFrame`. A frame with more is refused unparsed
#: (a ``too_large`` notice), so that a frame of thousands of unknown keys costs no validation.
MAX_FRAME_KEYS: Final = len(SensorFrame.model_fields)


_NOT_ESTIMATED: Final = (
    "the primary estimator's, else the first healthy estimator's that estimates it (named in sources); "
    "null: not estimated"
)


class GaitState(BaseModel):
    """The estimate at one sample, as streamed to browsers and recorded (``/gait_state``)."""

    seq: int
    t: float
    phase: float | None = Field(description="the primary estimator's gait phase (null: no estimator drives the torque)")
    phase_rate: float | None = Field(description=_NOT_ESTIMATED)
    stride_length_m: float | None = Field(description=_NOT_ESTIMATED)
    incline_deg: float | None = Field(description=_NOT_ESTIMATED)
    torque_Nm: float
    tbe_phase: float | None = Field(description="the timing-based estimate's phase (null: not in the stack, or failed)")
    heel_strike: bool
    backup_reset: bool
    fault: bool = Field(default=False, description="the filters were reset or the torque forced to 0 here")
    foot_angle_deg: float | None
    shank_angle_deg: float | None
    thigh_angle_deg: float | None
    foot_pred_deg: float | None = Field(description=_NOT_ESTIMATED)
    shank_pred_deg: float | None = Field(description=_NOT_ESTIMATED)
    sent_ns: int | None = None
    recv_ns: int = Field(description="server wall clock when the sensor frame arrived (ns)")
    sources: dict[str, str] | None = Field(
        default=None,
        description=(
            "which estimator each quantity comes from (phase, phase_rate, stride_length_m, incline_deg, "
            "foot_pred_deg, shank_pred_deg -> estimator name; a quantity absent is not estimated), on the first "
            "state of a stream or recording and where it changed (a primary switch, a failure); null: unchanged"
        ),
    )
    torque_assumes: dict[str, float] | None = Field(
        default=None,
        description=(
            "with sources: the values the torque profile takes for what the primary does not estimate "
            "(stride_length_m in m, incline_deg in deg); they drive the torque only, never shown as estimates"
        ),
    )


class TorqueCommand(BaseModel):
    """Sent back to a live device after each frame, and recorded (``/torque``)."""

    type: Literal["torque"] = "torque"
    seq: int
    t: float
    torque_Nm: float


class EstimatorOutputs(BaseModel):
    """One estimator's outputs at one sample, recorded on its own channel (``/estimators/<name>``).

    ``values`` maps each output the estimator declares (``gaitscope.estimators.protocol.Estimator.outputs``) to its
    value (booleans as 1.0 / 0.0), None for all of them once the estimator has failed.
    """

    seq: int
    t: float
    name: str
    values: dict[str, float | None]
    failed: bool = False


class EstimatorColumns(BaseModel):
    """One estimator's outputs over a :class:`StreamBatch`: one column per output, row for row with the
    batch's states (None where it had failed)."""

    failed: bool = Field(description="it has failed (its outputs are no longer computed)")
    columns: dict[str, list[float | None]]


class StreamBatch(BaseModel):
    """Server -> browser: the gait states since the last batch (decimated as the client asked), and every
    estimator's outputs at the same samples."""

    type: Literal["states"] = "states"
    session_id: int
    states: list[GaitState]
    decimation: int = Field(description="every n-th sample is sent")
    estimators: dict[str, EstimatorColumns] = Field(
        default_factory=dict, description="by estimator name, aligned with states"
    )


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
    disk_minutes: float | None = Field(
        default=None,
        description="minutes of recording left at this session's rate before the disk guard stops it (null: unknown)",
    )
    estimators: list[str] = Field(default_factory=list, description="the session's estimator stack")
    primary: str | None = Field(
        default=None, description="the estimator driving the torque now (null: none, the torque is 0)"
    )
    failed_estimators: dict[str, str] = Field(default_factory=dict, description="failed estimators and why")
    tracking: Literal["walking", "standing", "lost"] | None = Field(
        default=None,
        description="the primary's gait tracking (estimators.lock): walking; standing still (phase held, torque "
        "0); lost (it lost track and was reset in the last 5 s); null: no primary yet",
    )
    tracking_note: str = Field(default="", description="why it lost track (when tracking is lost)")
    imu: Literal["ok", "fault"] | None = Field(
        default=None,
        description="the IMU front ends (estimators.imu_frontend, sessions.live.imu_events): ok; fault (a sensor "
        "has reported a problem for 0.3 s of the last second, and not yet been clear for a second); null: the stack "
        "derives no angle from raw IMUs",
    )
    imu_note: str = Field(
        default="",
        description="the worst IMU problem open, naming the sensor, in the clinician's words, and how many more are "
        "open (when imu is fault)",
    )


#: An ``invalid`` :class:`DeviceNotice` lists at most this many of the frame's errors (``errors`` counts them all).
MAX_NOTICE_ERRORS: Final = 5


class DeviceNotice(BaseModel):
    """Server -> device, instead of a torque command: why a frame was refused or dropped.

    ``kind``: ``invalid`` (the frame failed validation; ``detail`` lists the first
    :data:`MAX_NOTICE_ERRORS` errors, without the input, and ``errors`` counts them all), ``too_large``
    (a frame longer than :data:`MAX_FRAME_BYTES`, or with more keys than a frame has: refused unparsed;
    ``detail`` gives its size and the limit), ``order`` (its time does not follow the last frame's),
    ``rate`` (frames over the declared rate were dropped; ``dropped`` counts them since the last notice),
    ``binary`` (a binary message; frames are JSON text). A notice never carries what the device sent.
    """

    type: Literal["error"] = "error"
    kind: Literal["invalid", "too_large", "order", "rate", "binary"]
    detail: str | list[dict[str, Any]]
    seq: int | None = None
    dropped: int = 0
    errors: int = Field(default=0, description="invalid: how many errors the frame had (detail lists the first few)")


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
    "/imu_calibration": ("gaitscope.ImuCalibration", ImuCalibration),
    "/gp_models": ("gaitscope.GPModelRecord", GPModelRecord),
    "/estimation_state": ("gaitscope.EstimationState", EstimationState),
}
#: Each estimator of a session's stack records its outputs on ``/estimators/<name>`` with this schema:
#: channels registered per stack (:func:`estimator_channels`), beside the fixed ones above.
ESTIMATOR_TOPIC_PREFIX: Final = "/estimators/"
ESTIMATOR_SCHEMA: Final[tuple[str, type[BaseModel]]] = ("gaitscope.EstimatorOutputs", EstimatorOutputs)


def estimator_channels(names: Iterable[str]) -> dict[str, tuple[str, type[BaseModel]]]:
    """The MCAP channels of a stack's estimators: topic -> (schema name, class), as :data:`MCAP_CHANNELS`."""
    return {f"{ESTIMATOR_TOPIC_PREFIX}{name}": ESTIMATOR_SCHEMA for name in names}


# =================================================================================================
# People, sessions, reports (issue #12 section 4): a stopped session's summary and its exports
# (gaitscope.sessions.reports, server/routes/reports.py).
# =================================================================================================


class StrideProfilePoint(BaseModel):
    """One stride of a session: when it started, its speed and incline (the speed and incline profile)."""

    trial_id: int
    t: float = Field(description="session time (s) of the heel strike that starts it")
    duration_s: float
    speed_m_s: float = Field(description="estimated stride length over the stride's duration")
    incline_deg: float = Field(description="mean estimated incline over the stride")
    after_gap: bool = Field(
        default=False,
        description="the first stride of its trial, or one after time not recorded or not usable: a profile's "
        "line breaks before it rather than bridge the gap",
    )


class StrideCondition(BaseModel):
    """The strides walked at one condition (speed and incline, binned), as curves over the stride (0-100 %).

    ``mean`` and every row of ``strides`` have one value per point of ``percent`` (None where the signal was
    missing); ``strides`` keeps at most :data:`SUMMARY_MAX_OVERLAY` of them (evenly spread)."""

    label: str
    speed_m_s: float
    incline_deg: float
    strides: int
    percent: list[float]
    signals: dict[str, list[float | None]] = Field(description="signal -> mean curve")
    overlays: dict[str, list[list[float | None]]] = Field(description="signal -> a few single strides' curves")


class DataHealthFigures(BaseModel):
    """How good the session's data is, over every recorded trial."""

    samples: int
    recorded_s: float
    rate_hz: float | None = Field(description="median sample rate; null without samples")
    gaps: int = Field(description="breaks in the data longer than three sample periods")
    longest_gap_s: float
    missing_percent: float = Field(description="samples without a measured thigh, shank or foot angle, in %")
    faults: int = Field(description="samples at which the filters were reset or the torque forced to 0")
    backup_resets: int
    trials_recovered: int
    trials_damaged: int


class SettingChangeRow(BaseModel):
    """One setting change, in words a clinician reads."""

    t: float
    wall_utc: str
    text: str = Field(description='e.g. "Torque gain 1.00 -> 1.30, by clinician"')


class SessionSummary(BaseModel):
    """What a stopped session gives: ``GET /api/sessions/{id}/summary`` (the same of one trial: a trial's report)."""

    session_id: int
    trial_id: int | None = Field(default=None, description="the one trial summarized; null: the whole session")
    subject_id: int
    subject_code: str
    state: SessionState
    source: str = Field(description="in words: simulated walker, replay of a trial, live device, upload")
    started_utc: str | None
    stopped_utc: str | None
    duration_s: float = Field(description="recorded time: the sum of the trials' recorded durations (s)")
    wall_s: float | None = Field(
        default=None, description="the session's wall time from start to stop (s); null while it has not stopped"
    )
    trials: list[Trial]
    strides: int
    transition_strides: int = Field(
        default=0,
        description="usable strides in no condition: walked while the speed or incline changed "
        "(see gaitscope.sessions.reports.summary)",
    )
    mean_speed_m_s: float | None
    mean_stride_length_m: float | None
    mean_cadence_spm: float | None = Field(description="strides per minute")
    profile: list[StrideProfilePoint]
    settings_start: SessionSettings | None = Field(description="in force when the first trial started")
    settings_end: SessionSettings
    settings_history: list[SettingChangeRow]
    conditions: list[StrideCondition]
    health: DataHealthFigures
    events: list[Event]


#: Overlaid single strides kept per condition and signal in a summary.
SUMMARY_MAX_OVERLAY: Final = 12

ExportKind = Literal["pdf", "csv"]


class ExportCreate(_Strict):
    """``POST /api/sessions/{id}/exports`` (a whole session) or ``POST /api/trials/{id}/exports`` (one trial):
    a PDF report or a CSV of the estimates."""

    kind: ExportKind


class ExportJob(BaseModel):
    """An export being made (``GET /api/exports/{id}``); its file is ``GET /api/exports/{id}/file`` once done."""

    id: str
    session_id: int
    trial_id: int | None = Field(default=None, description="the one trial exported; null: the whole session")
    kind: ExportKind
    state: Literal["running", "done", "failed"]
    progress: float = Field(ge=0.0, le=1.0)
    step: str = Field(description="what it is doing, in words")
    filename: str
    error: str = ""


class SummaryProgress(BaseModel):
    """``GET /api/sessions/{id}/summary/progress``: how far the making of a session's summary has got, for the
    page waiting for it (a long session's recordings take seconds to read)."""

    running: bool = Field(description="a summary of the session is being made now")
    cached: bool = Field(description="the summary of the session as its trials are now is ready (kept)")
    progress: float = Field(ge=0.0, le=1.0, description="fraction of the gait states read")
    step: str = Field(description="what it is doing, in words")


# --- review: A/B comparison of re-runs and review annotations (issue #12; gaitscope.sessions.review.compare) ---------
# (The lead may add these to WIRE for web/wire.js; they are served by /api/trials/{id}/compare and /annotations.)

#: Most re-runs one comparison runs side by side (each is a full re-run of the trial's frames).
MAX_COMPARED_RUNS: Final = 4


class ComparedRunSpec(_Strict):
    """One re-run of an A/B comparison: its name (the user's) and how it runs (as :class:`RerunRequest`)."""

    name: str = Field(min_length=1, max_length=40, description="the name the user gives it ('A', 'gain 1.3')")
    settings: SessionSettings | None = Field(
        default=None, description="null: the recorded settings and their changes (what ran); else held over the trial"
    )
    estimators: list[EstimatorName] | None = Field(default=None, max_length=16, description="null: the recorded stack")

    @field_validator("name")
    @classmethod
    def _named(cls, v: str) -> str:
        v = v.strip()
        if not v:
            raise ValueError("a re-run's name must not be blank")
        return v


class CompareRequest(_Strict):
    """Two or more re-runs of one trial compared (``POST /api/trials/{id}/compare``); the first is the reference."""

    runs: list[ComparedRunSpec] = Field(min_length=2, max_length=MAX_COMPARED_RUNS)

    @model_validator(mode="after")
    def _unique_names(self) -> CompareRequest:
        seen: set[str] = set()
        for run in self.runs:
            key = run.name.casefold()
            if key in seen:
                raise ValueError(f"two re-runs are named {run.name!r}: give each its own name")
            seen.add(key)
        return self


class RunFigures(BaseModel):
    """Figures of one re-run over the compared window; errors only when the trial's ground truth is known."""

    strides: int = Field(description="complete strides (heel strike to heel strike, 0.3-4 s)")
    peak_torque_Nm: float | None = Field(description="mean over the strides of each stride's peak torque command")
    mean_phase_rate_1_s: float | None = Field(description="mean estimated phase rate (strides per second)")
    mean_stride_length_m: float | None = Field(description="mean estimated stride length")
    phase_rmse_pct: float | None = Field(default=None, description="RMS phase error against the truth (% of a cycle)")
    phase_rate_rmse_1_s: float | None = Field(default=None, description="RMS phase-rate error against the truth")
    stride_length_rmse_m: float | None = Field(default=None, description="RMS stride-length error against the truth")
    incline_rmse_deg: float | None = Field(default=None, description="RMS incline error against the truth")


class ComparedRun(BaseModel):
    """One re-run's figures, its time series (on the comparison's ``t``) and its mean stride."""

    name: str
    figures: RunFigures
    torque_Nm: list[float | None] = Field(description="torque command, row for row with the comparison's t")
    phase_pct: list[float | None] = Field(description="phase (% of the gait cycle), row for row with t")
    torque_diff_Nm: list[float | None] = Field(description="this run's torque minus the first run's")
    phase_diff_pct: list[float | None] = Field(description="this run's phase minus the first run's, wrapped to ±50 %")
    stride_torque_mean_Nm: list[float | None] = Field(description="mean torque per % of the stride (stride_pct)")
    stride_torque_sd_Nm: list[float | None] = Field(description="its standard deviation across strides")
    start: str = Field(
        default="",
        description="how its estimators began: resumed from the estimation state recorded at the trial's start "
        "(a run as recorded: what ran, exactly), or fresh filters and why (the re-run's start)",
    )


class Comparison(BaseModel):
    """The answer of ``POST /api/trials/{id}/compare``."""

    t: list[float] = Field(description="session time (s) of the rows, decimated keeping every series' extremes")
    stride_pct: list[float] = Field(description="0-100 % of the stride, the x of the runs' mean strides")
    ground_truth: str | None = Field(description="where the truth the errors are against comes from; null: none known")
    runs: list[ComparedRun]


class ReviewAnnotationCreate(_Strict):
    """A note added in review at a time, or over a span, of a trial (``POST /api/trials/{id}/annotations``)."""

    t: float = Field(ge=0.0, le=1e9, allow_inf_nan=False, description="session time (s) it is at (or starts at)")
    t_end: float | None = Field(
        default=None, ge=0.0, le=1e9, allow_inf_nan=False, description="end of its span (s); null: a single time"
    )
    text: str = Field(min_length=1, max_length=500)
    actor: str = _ACTOR

    @field_validator("text", "actor")
    @classmethod
    def _not_blank(cls, v: str) -> str:
        v = v.strip()
        if not v:
            raise ValueError("must not be blank")
        return v

    @model_validator(mode="after")
    def _span(self) -> ReviewAnnotationCreate:
        if self.t_end is not None and self.t_end <= self.t:
            raise ValueError(f"the span must end after it starts (t_end {self.t_end:g} s <= t {self.t:g} s)")
        return self


class ReviewAnnotation(ReviewAnnotationCreate):
    """A note of a trial: added in review, or taken live during its recording (an ``annotation`` event of the
    session logged while the trial recorded: its ``id`` is the event's, and it is not deleted from review)."""

    id: int
    trial_id: int
    created_utc: str
    source: Literal["review", "live"] = Field(
        default="review", description="review: added in review (its author may delete it); live: taken live"
    )


# --- live view: undo the last settings change (issue #12) --------------------------------------------------


class SettingsUndo(_Strict):
    """Undo the session's last applied settings change (``POST /api/sessions/{id}/settings/undo``): its fields go
    back to their values before it, within the same bounds and rate limits as any change, logged as a change."""

    actor: str = _ACTOR
    confirm: bool = Field(
        default=False,
        description="as SettingsChange.confirm: an undo that can raise the torque on the person needs it",
    )


# --- accounts, roles, device credentials (issue #13) ---------------------------------------------------

#: What a role may do (``server/auth``'s ``PERMISSIONS`` says which role holds which).
Role = Literal["admin", "clinician", "experimenter", "viewer"]
ROLES: Final[tuple[Role, ...]] = ("admin", "clinician", "experimenter", "viewer")
Permission = Literal[
    "read", "run", "annotate", "upload", "assist", "assist_within_limits", "promote", "set_limits", "admin"
]
#: A user name: lower case, starts with a letter, 2-32 characters of letters, digits, ``_ . -``.
USER_NAME = r"^[a-z][a-z0-9_.-]{1,31}$"
#: Passwords: at least this long (NIST SP 800-63B asks for 8 at least; a clinic's shared tablets get 10).
PASSWORD_MIN: Final = 10
PASSWORD_MAX: Final = 256


class User(BaseModel):
    """An account (never its password hash)."""

    id: int
    name: str
    role: Role
    disabled: bool = False
    created_utc: str
    created_by: str
    last_login_utc: str | None = None
    failed_logins: int = Field(default=0, description="failed logins at this name since the last good one")
    locked_until_utc: str | None = Field(
        default=None,
        description="addresses that failed at this name wait until then (an address that has not failed never waits)",
    )


class UserCreate(_Strict):
    name: str = Field(pattern=USER_NAME)
    role: Role
    password: str = Field(min_length=PASSWORD_MIN, max_length=PASSWORD_MAX)


class UserChange(_Strict):
    """An admin's change of an account; fields left out keep their value."""

    role: Role | None = None
    disabled: bool | None = None
    unlock: bool = Field(default=False, description="end a lockout now and reset the failed-login count")
    password: str | None = Field(
        default=None, min_length=PASSWORD_MIN, max_length=PASSWORD_MAX, description="set a new password (a reset)"
    )


class LoginRequest(_Strict):
    name: str = Field(min_length=1, max_length=64)
    password: str = Field(min_length=1, max_length=PASSWORD_MAX)


class PasswordChange(_Strict):
    current: str = Field(min_length=1, max_length=PASSWORD_MAX)
    new: str = Field(min_length=PASSWORD_MIN, max_length=PASSWORD_MAX)


class Me(BaseModel):
    """Who the server takes the caller to be (``GET /api/auth/me``)."""

    name: str
    role: Role
    accounts: bool = Field(description="accounts are on: a login is needed; off: loopback only, everyone is 'local'")
    permissions: list[Permission]
    csrf_token: str | None = Field(
        default=None, description="send it as the X-CSRF-Token header with every state-changing request"
    )


class DeviceToken(BaseModel):
    """A device's credential for one session's ``/ws/devices/{id}``; ``token`` is shown once, when issued."""

    id: int
    session_id: int
    prefix: str = Field(description="its first characters, to tell tokens apart (the token itself is never stored)")
    created_utc: str
    created_by: str
    revoked_utc: str | None = None
    revoked_by: str | None = None
    token: str | None = Field(default=None, description="the token: present only in the answer that issued it")


class AssistanceLimits(_Strict):
    """The most assistance an experimenter may set for a subject, set by a clinician. An experimenter may
    change torque gain, torque bound and intent boost only up to these (and lower them freely); noise scales
    are estimator tuning, not assistance, and are theirs to change."""

    torque_gain: float = _setting("torque_gain", 1.0)
    max_torque_Nm: float = _setting("max_torque_Nm", 30.0)
    intent_gain_boost: float = _setting("intent_gain_boost", 0.0)


class SubjectLimits(AssistanceLimits):
    subject_id: int
    set_by: str
    set_utc: str


# --- audit trail (issue #13) -------------------------------------------------------------------------------

#: How a recorded action ended: ``requested`` (written before the change takes effect), ``done``, ``failed`` (a
#: failed login, a change that raised) or ``refused`` (401/403/409/422 on a state-changing request).
AuditOutcome = Literal["requested", "done", "failed", "refused"]
AUDIT_OUTCOMES: Final[tuple[AuditOutcome, ...]] = ("requested", "done", "failed", "refused")
#: The hash before the first entry's: 64 zeros.
AUDIT_GENESIS: Final = "0" * 64
AUDIT_PAGE_MAX: Final = 1000


def _audit_time(v: str | None) -> str | None:
    """An ISO-8601 time (a date alone is its midnight; no zone is UTC) as the audit table stores times."""
    import datetime as dt

    if v is None:
        return None
    try:
        t = dt.datetime.fromisoformat(v.strip().replace("Z", "+00:00"))
    except ValueError:
        raise ValueError(f"not an ISO-8601 date or time: {v!r}") from None
    t = t.replace(tzinfo=dt.UTC) if t.tzinfo is None else t.astimezone(dt.UTC)
    return t.isoformat(timespec="milliseconds")


class AuditEntry(BaseModel):
    """One entry of the audit trail (``gaitscope.sessions.audit``): who did what to what, when, and how it ended.

    ``before`` and ``after`` are JSON text exactly as hashed (null: nothing). ``hash`` is the SHA-256 of the
    entry's canonical JSON including ``prev_hash``, the previous entry's ``hash`` (``sessions/audit/log.py``
    says how, so that anyone can re-check the chain with other tools)."""

    id: int
    seq: int = Field(ge=1, description="1, 2, 3... without gaps: a missing number is a deleted entry")
    time_utc: str = Field(description="ISO-8601 UTC, to the millisecond")
    user: str
    role: str = Field(description="the user's role then; 'none' for a caller nobody knows")
    action: str = Field(description="what was asked, dotted ('session.start', 'settings.change', 'login')")
    target: str = Field(description="what it was done to ('session 7', a path)")
    before: str | None = Field(default=None, description="JSON text: the state before the change")
    after: str | None = Field(default=None, description="JSON text: the state asked for")
    outcome: AuditOutcome
    detail: str = ""
    prev_hash: str = Field(pattern=r"^[0-9a-f]{64}$")
    hash: str = Field(pattern=r"^[0-9a-f]{64}$")
    mac: str | None = Field(
        default=None,
        pattern=r"^[0-9a-f]{64}$",
        description="HMAC-SHA256 of ``hash`` under the audit key (null: written before the trail was keyed)",
    )


class AuditQuery(_Strict):
    """Filters of ``GET /api/audit`` and its CSV: all given ones must hold; newest entries first."""

    user: str | None = Field(default=None, min_length=1, max_length=64, description="exactly this user")
    action: str | None = Field(default=None, min_length=1, max_length=128, description="actions starting so")
    outcome: AuditOutcome | None = None
    target: str | None = Field(default=None, min_length=1, max_length=256, description="targets starting so")
    since: str | None = Field(default=None, max_length=40, description="from this time on (ISO-8601, UTC if no zone)")
    until: str | None = Field(default=None, max_length=40, description="before this time (exclusive)")
    limit: int = Field(default=100, ge=1, le=AUDIT_PAGE_MAX)
    offset: int = Field(default=0, ge=0, le=INT64_MAX)

    @field_validator("since", "until")
    @classmethod
    def _time(cls, v: str | None) -> str | None:
        return _audit_time(v)

    @model_validator(mode="after")
    def _ordered(self) -> AuditQuery:
        if self.since is not None and self.until is not None and self.since >= self.until:
            raise ValueError(f"since ({self.since}) must be before until ({self.until})")
        return self


class AuditVerification(BaseModel):
    """What ``gaitscope audit verify`` (and ``GET /api/audit/verify``) found."""

    ok: bool
    entries: int = Field(description="entries checked (all of them when ok)")
    first_bad_seq: int | None = Field(default=None, description="where the chain first breaks")
    problem: str | None = Field(default=None, description="why, in words ('hash mismatch at seq 17 ...')")
    last_hash: str | None = Field(
        default=None, description="the newest entry's hash: note it elsewhere to detect a cut-off tail later"
    )
    keyed_from: int | None = Field(
        default=None,
        description="the first entry with a MAC; those before it (written before the trail was keyed) are "
        "checked by the SHA-256 chain only. Null: no keyed entry",
    )
    checkpoint_seq: int | None = Field(
        default=None, description="the checkpoint checked against: no entry up to this seq was cut or rewritten"
    )


class AuditCheckpoint(_Strict):
    """The audit trail's head at a moment, signed with the audit key: the file ``gaitscope audit checkpoint``
    writes, for the admin to keep away from the database. ``gaitscope audit verify --checkpoint FILE`` then
    proves that no entry up to ``seq`` was cut off or rewritten since (``sessions/audit/log.py``)."""

    format: Literal["gaitscope-audit-checkpoint/1"] = "gaitscope-audit-checkpoint/1"
    seq: int = Field(ge=0, le=INT64_MAX, description="how many entries the trail had (the newest one's seq)")
    hash: str = Field(pattern=r"^[0-9a-f]{64}$", description="the newest entry's hash (64 zeros: no entry)")
    time_utc: str = Field(max_length=40, description="when the checkpoint was made (ISO-8601 UTC)")
    mac: str = Field(
        pattern=r"^[0-9a-f]{64}$",
        description="HMAC-SHA256 under the audit key of the canonical JSON of the other fields",
    )


#: Every class that crosses a socket or a file, as ``GET /api/schema`` serves them and ``web/wire.js``
#: types them (the classes they refer to come along in their JSON schemas' ``$defs``).
WIRE: Final[tuple[type[BaseModel], ...]] = (
    SubjectCreate, Subject, SessionCreate, Session, ClusterNode, SessionSettings, SettingsChange, Trial, Event,
    AnnotationCreate, RecordingControl, UploadCreate, Upload, RerunRequest, RerunChoices, ModelInfo, ViewerFocus,
    ViewerShow, SensorFrame, GaitState, TorqueCommand, StreamBatch, Health, EventMessage, SettingsMessage, Hello,
    FoxgloveEvent, ModelProvenance, DeviceNotice, EstimatorOutputs, CalibrationRequest, PersonalizationChange,
    Personalization, CohortPoint, Fingerprints, PersonalizationExport, IntentSeries, ImuCalibrationRequest,
    ImuCalibration, ImuCalibrationStatus, GPArray, GPModelRecord, EstimationState, GPModelInfo, GPBand, GPPendingFit,
    GPLearningState, GPLearningControl, SessionSummary, SummaryProgress, ExportCreate, ExportJob, CompareRequest,
    Comparison, ReviewAnnotationCreate, ReviewAnnotation, SettingsUndo, User, UserCreate, UserChange, LoginRequest,
    PasswordChange, Me, DeviceToken, AssistanceLimits, SubjectLimits, AuditEntry, AuditQuery, AuditVerification,
    TorqueRaiseRefused, TorqueCheck, RegisteredEstimator,
)  # fmt: skip

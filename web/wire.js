// GENERATED from sessions/schema.py and sessions/registry.py by `gaitscope wire --out web/wire.js`:
// do not edit by hand. Change them and run the command again; tests/server/test_wire.py fails while this
// file differs from what they generate.
//
// JSDoc types of every wire message (the JSON schemas `GET /api/schema` serves, as types), the
// bounds the browser checks before the server does (the server stays the judge: 422, 409), and the
// registered estimators.

/**
 * A person who walks with a device.
 * @typedef {object} SubjectCreate
 * @property {string} code pseudonymous code, 1-32 of A-Z a-z 0-9 _ . -
 * @property {number} leg_length_m (0.5..1.3)
 * @property {number} mass_kg (20..250)
 * @property {"left" | "right"} [side="right"]
 * @property {string} [notes=""]
 */

/**
 * @typedef {object} Subject
 * @property {string} code pseudonymous code, 1-32 of A-Z a-z 0-9 _ . -
 * @property {number} leg_length_m (0.5..1.3)
 * @property {number} mass_kg (20..250)
 * @property {"left" | "right"} [side="right"]
 * @property {string} [notes=""]
 * @property {number} id
 * @property {string} created_utc
 */

/**
 * @typedef {object} SessionCreate
 * @property {number} subject_id (1..9223372036854775807)
 * @property {SimulatedSource | ReplaySource | DeviceSource | LslSource | UploadSource} [source]
 * @property {SessionSettings} [settings]
 * @property {boolean} [start=true]
 */

/**
 * @typedef {object} Session
 * @property {number} id
 * @property {number} subject_id
 * @property {SimulatedSource | ReplaySource | DeviceSource | LslSource | UploadSource} source
 * @property {SessionSettings} settings
 * @property {"created" | "running" | "stopped" | "failed"} state
 * @property {string} created_utc
 * @property {string | null} [started_utc=null]
 * @property {string | null} [stopped_utc=null]
 * @property {string | null} [node=null] the server process that runs (or ran) it: several may share one database
 */

/**
 * A gaitscope process sharing this database (``GET /api/cluster/nodes``; ``sessions/cluster``).
 * @typedef {object} ClusterNode
 * @property {string} name its node name (GAITSCOPE_NODE)
 * @property {string} address host:port the proxy reaches it at
 * @property {"up" | "gone"} state gone: its beat stopped and another node took its sessions over
 * @property {string} seen_utc its last beat, ISO-8601 UTC
 * @property {number} running sessions it runs (>= 0)
 * @property {boolean} live up, with a beat younger than the timeout
 * @property {boolean} this the node that answered
 */

/**
 * Assistance and estimator tuning of one session (seed 000's defaults at 1.0).
 * @typedef {object} SessionSettings
 * @property {number} [torque_gain=1.0] x the 1/5-scaled biological moment (0..3)
 * @property {number} [max_torque_Nm=30.0] hard bound on the command (0..80)
 * @property {number} [measurement_noise_scale=1.0] (0.1..10)
 * @property {number} [process_noise_scale=1.0] (0.1..10)
 * @property {number} [intent_gain_boost=0.0] assistance follows intent (beyond seed 001; 0: off): while the intent estimator says speeding up (slowing down) the torque gain rises (falls) by up to this fraction, scaled by its confidence (0..0.3)
 * @property {string} [model="default"] name of a model in the model store
 * @property {string} [primary="phase_ekf"] the estimator of the stack whose phase drives the torque profile
 * @property {Array<string> | null} [estimators=null] the session's estimator stack, chosen at start and fixed while it runs; null: every estimator the source's channels allow
 * @property {boolean} [lsl_outlet=false] publish the gait state as a Lab Streaming Layer outlet (type GaitState) while the session runs, for the lab's recorder; fixed at start
 */

/**
 * A requested change of some settings; fields left out keep their value.
 * @typedef {object} SettingsChange
 * @property {number | null} [torque_gain=null] (0..3)
 * @property {number | null} [max_torque_Nm=null] (0..80)
 * @property {number | null} [measurement_noise_scale=null] (0.1..10)
 * @property {number | null} [process_noise_scale=null] (0.1..10)
 * @property {number | null} [intent_gain_boost=null] (0..0.3)
 * @property {string | null} [primary=null] switched at most every 2 s; the torque blends over 0.5 s
 * @property {string} [actor="local"] set by the server to the logged-in user; ignored if sent
 * @property {string} [reason=""]
 * @property {boolean} [confirm=false] the user confirmed a change that can raise the torque on the person (a raise of the torque gain, the maximum torque or the intent boost, or a switch of the primary), having been shown its peak torque before and after; without it such a change is refused (409, a TorqueRaiseRefused), and at most one is made every 3 s. Lowering needs no confirmation and is never held back
 */

/**
 * @typedef {object} Trial
 * @property {number} id
 * @property {number} session_id
 * @property {string} name
 * @property {"recording" | "finished" | "recovered" | "uploaded" | "damaged"} status
 * @property {string} path MCAP file, relative to the data folder
 * @property {string} started_utc
 * @property {string | null} [stopped_utc=null]
 * @property {number} [samples=0]
 * @property {number} [duration_s=0.0]
 */

/**
 * A setting change, an annotation, a system event or a detected speed-change intent: when, what,
 * before, after, who.
 * @typedef {object} Event
 * @property {number} id
 * @property {number} session_id
 * @property {number} t session time (s) of the sample at which it took effect
 * @property {string} wall_utc
 * @property {"setting" | "annotation" | "system" | "recording" | "intent"} kind
 * @property {string} text
 * @property {string | null} [field=null]
 * @property {number | string | null} [before=null]
 * @property {number | string | null} [after=null]
 * @property {string} [actor="system"]
 */

/**
 * @typedef {object} AnnotationCreate
 * @property {string} text
 * @property {string} [actor="local"] set by the server to the logged-in user; ignored if sent
 */

/**
 * @typedef {object} RecordingControl
 * @property {"start" | "stop"} action
 * @property {string} [name=""]
 */

/**
 * @typedef {object} UploadCreate
 * @property {string} filename
 * @property {number} size bytes; refused above the server's limit (1..9223372036854775807)
 * @property {number} subject_id (1..9223372036854775807)
 */

/**
 * @typedef {object} Upload
 * @property {string} id
 * @property {string} filename
 * @property {number} size
 * @property {number} received
 * @property {number} chunk_size
 */

/**
 * A re-run of a recorded trial's sensor frames through the estimators (``POST /api/trials/{id}/rerun``).
 *
 * Two modes, by ``settings``:
 *
 * * left out or null (the default): **as recorded**. The trial's recorded settings are replayed: those
 *   in force at its first frame, then each recorded change (``/settings``) from the frame after the one
 *   it followed, as it applied live; the model is the recorded one. The result reproduces the recorded
 *   gait states to floating-point round-off: the baseline of "what ran".
 * * given: **what if**. These settings, model included, held constant over the whole trial (recorded
 *   changes are not applied).
 * @typedef {object} RerunRequest
 * @property {SessionSettings | null} [settings=null] null: as recorded (the default); else these settings over the whole trial
 * @property {Array<string> | null} [estimators=null] the estimators to re-run (their outputs come back as '<name>.<output>' columns); null: the trial's recorded stack
 * @property {number | null} [personalization_id=null] the subject's personalization whose fingerprint fp_ls runs (compare before promoting); null: the subject's active one, if any (1..9223372036854775807)
 */

/**
 * Which estimators a re-run of a recorded trial can run (``GET /api/trials/{id}/estimators``): what a
 * review's picker offers. Any subset of ``runnable`` may be asked for (``RerunRequest.estimators``); the
 * server stays the judge (a subset without the estimator that derives a channel another needs is 422).
 * @typedef {object} RerunChoices
 * @property {Array<string> | null} recorded the stack the trial was recorded with, in the order it ran; null: not recorded (a log from another tool)
 * @property {Array<string>} default what a re-run without 'estimators' runs: the recorded stack, else every estimator the trial's channels allow but the opt-in ones
 * @property {Array<string>} runnable the registered estimators the trial's channels can feed (the recorded ones ran), in the order a stack runs them
 * @property {Object<string, Object<string, Array<string>>>} [derived] of a runnable estimator, each channel it requires that the trial lacks, with the estimators before it that derive it (one of them must run too)
 * @property {Object<string, string>} [refused] the other registered estimators, each with why it cannot run
 */

/**
 * A model in the model store (``GET /api/models``).
 * @typedef {object} ModelInfo
 * @property {string} name
 * @property {ModelProvenance} provenance
 */

/**
 * Which running session the leg view follows (``POST /api/viewer/focus``).
 * @typedef {object} ViewerFocus
 * @property {number} session_id (1..9223372036854775807)
 */

/**
 * Pose the leg view at time ``t`` (s) of a trial: the review page's cursor (``POST /api/viewer/show``).
 * @typedef {object} ViewerShow
 * @property {number} trial_id (1..9223372036854775807)
 * @property {number} t session time (s), finite, within 30 years (-1e+09..1e+09)
 */

/**
 * One sample from a device (``/ws/devices/{id}``) or a source; absent channel = None.
 *
 * Every channel of :data:`CHANNELS` is optional; units and sign conventions are in each field's
 * description (and the registry). ``t`` is the device's own clock (s) and must be a finite number: a
 * frame without a usable time is refused. Channel values outside :data:`SENSOR_LIMITS` (or NaN /
 * Infinity) are accepted here and treated as missing by :meth:`plausible`, which the estimators run on
 * every frame. ``sent_ns`` is the device's wall clock at send time (ns since the epoch, optional) for
 * end-to-end latency.
 *
 * Versions: a frame without ``version`` is read as the current one. Version 1 frames (recordings,
 * replay files and device clients from before version 2, whose channels keep their names, units and
 * meanings in version 2) are accepted and upgraded on read: the frame read says ``version=2``.
 * @typedef {object} SensorFrame
 * @property {"frame"} [type="frame"]
 * @property {1 | 2} [version=2] schema version; 1 is upgraded on read
 * @property {number} seq (0..9223372036854775807)
 * @property {number} t
 * @property {number | null} [foot_angle_deg=null] ipsilateral foot angle from horizontal, (+) toes up (deg)
 * @property {number | null} [foot_vel_dps=null] ipsilateral foot angular velocity (deg/s)
 * @property {number | null} [shank_angle_deg=null] ipsilateral shank angle from vertical (deg)
 * @property {number | null} [shank_vel_dps=null] ipsilateral shank angular velocity (deg/s)
 * @property {number | null} [heel_forward_m=null] ipsilateral heel forward of the hip, raw (not high-passed) (m)
 * @property {number | null} [heel_up_m=null] ipsilateral heel above the hip, raw (not high-passed) (m)
 * @property {number | null} [thigh_angle_deg=null] ipsilateral thigh angle from vertical (deg)
 * @property {number | null} [thigh_vel_dps=null] ipsilateral thigh angular velocity (deg/s)
 * @property {number | null} [foot_angle_contra_deg=null] contralateral foot angle from horizontal, (+) toes up (deg)
 * @property {number | null} [foot_vel_contra_dps=null] contralateral foot angular velocity (deg/s)
 * @property {number | null} [shank_angle_contra_deg=null] contralateral shank angle from vertical (deg)
 * @property {number | null} [shank_vel_contra_dps=null] contralateral shank angular velocity (deg/s)
 * @property {number | null} [thigh_angle_contra_deg=null] contralateral thigh angle from vertical (deg)
 * @property {number | null} [thigh_vel_contra_dps=null] contralateral thigh angular velocity (deg/s)
 * @property {number | null} [hip_angle_deg=null] ipsilateral hip flexion (joint encoder) (deg)
 * @property {number | null} [knee_angle_deg=null] ipsilateral knee flexion (joint encoder) (deg)
 * @property {number | null} [ankle_angle_deg=null] ipsilateral ankle dorsiflexion (joint encoder) (deg)
 * @property {number | null} [hip_angle_contra_deg=null] contralateral hip flexion (joint encoder) (deg)
 * @property {number | null} [knee_angle_contra_deg=null] contralateral knee flexion (joint encoder) (deg)
 * @property {number | null} [ankle_angle_contra_deg=null] contralateral ankle dorsiflexion (joint encoder) (deg)
 * @property {number | null} [imu_pelvis_gyro_x_dps=null] pelvis (sacrum) IMU, rate about x (deg/s)
 * @property {number | null} [imu_pelvis_gyro_y_dps=null] pelvis (sacrum) IMU, rate about y (deg/s)
 * @property {number | null} [imu_pelvis_gyro_z_dps=null] pelvis (sacrum) IMU, rate about z (deg/s)
 * @property {number | null} [imu_pelvis_accel_x_m_s2=null] pelvis (sacrum) IMU, specific force along x (m/s^2)
 * @property {number | null} [imu_pelvis_accel_y_m_s2=null] pelvis (sacrum) IMU, specific force along y (m/s^2)
 * @property {number | null} [imu_pelvis_accel_z_m_s2=null] pelvis (sacrum) IMU, specific force along z (m/s^2)
 * @property {number | null} [imu_thigh_gyro_x_dps=null] ipsilateral thigh IMU, rate about x (deg/s)
 * @property {number | null} [imu_thigh_gyro_y_dps=null] ipsilateral thigh IMU, rate about y (deg/s)
 * @property {number | null} [imu_thigh_gyro_z_dps=null] ipsilateral thigh IMU, rate about z (deg/s)
 * @property {number | null} [imu_thigh_accel_x_m_s2=null] ipsilateral thigh IMU, specific force along x (m/s^2)
 * @property {number | null} [imu_thigh_accel_y_m_s2=null] ipsilateral thigh IMU, specific force along y (m/s^2)
 * @property {number | null} [imu_thigh_accel_z_m_s2=null] ipsilateral thigh IMU, specific force along z (m/s^2)
 * @property {number | null} [imu_shank_gyro_x_dps=null] ipsilateral shank IMU, rate about x (deg/s)
 * @property {number | null} [imu_shank_gyro_y_dps=null] ipsilateral shank IMU, rate about y (deg/s)
 * @property {number | null} [imu_shank_gyro_z_dps=null] ipsilateral shank IMU, rate about z (deg/s)
 * @property {number | null} [imu_shank_accel_x_m_s2=null] ipsilateral shank IMU, specific force along x (m/s^2)
 * @property {number | null} [imu_shank_accel_y_m_s2=null] ipsilateral shank IMU, specific force along y (m/s^2)
 * @property {number | null} [imu_shank_accel_z_m_s2=null] ipsilateral shank IMU, specific force along z (m/s^2)
 * @property {number | null} [imu_foot_gyro_x_dps=null] ipsilateral foot IMU, rate about x (deg/s)
 * @property {number | null} [imu_foot_gyro_y_dps=null] ipsilateral foot IMU, rate about y (deg/s)
 * @property {number | null} [imu_foot_gyro_z_dps=null] ipsilateral foot IMU, rate about z (deg/s)
 * @property {number | null} [imu_foot_accel_x_m_s2=null] ipsilateral foot IMU, specific force along x (m/s^2)
 * @property {number | null} [imu_foot_accel_y_m_s2=null] ipsilateral foot IMU, specific force along y (m/s^2)
 * @property {number | null} [imu_foot_accel_z_m_s2=null] ipsilateral foot IMU, specific force along z (m/s^2)
 * @property {number | null} [imu_thigh_contra_gyro_x_dps=null] contralateral thigh IMU, rate about x (deg/s)
 * @property {number | null} [imu_thigh_contra_gyro_y_dps=null] contralateral thigh IMU, rate about y (deg/s)
 * @property {number | null} [imu_thigh_contra_gyro_z_dps=null] contralateral thigh IMU, rate about z (deg/s)
 * @property {number | null} [imu_thigh_contra_accel_x_m_s2=null] contralateral thigh IMU, specific force along x (m/s^2)
 * @property {number | null} [imu_thigh_contra_accel_y_m_s2=null] contralateral thigh IMU, specific force along y (m/s^2)
 * @property {number | null} [imu_thigh_contra_accel_z_m_s2=null] contralateral thigh IMU, specific force along z (m/s^2)
 * @property {number | null} [imu_shank_contra_gyro_x_dps=null] contralateral shank IMU, rate about x (deg/s)
 * @property {number | null} [imu_shank_contra_gyro_y_dps=null] contralateral shank IMU, rate about y (deg/s)
 * @property {number | null} [imu_shank_contra_gyro_z_dps=null] contralateral shank IMU, rate about z (deg/s)
 * @property {number | null} [imu_shank_contra_accel_x_m_s2=null] contralateral shank IMU, specific force along x (m/s^2)
 * @property {number | null} [imu_shank_contra_accel_y_m_s2=null] contralateral shank IMU, specific force along y (m/s^2)
 * @property {number | null} [imu_shank_contra_accel_z_m_s2=null] contralateral shank IMU, specific force along z (m/s^2)
 * @property {number | null} [imu_foot_contra_gyro_x_dps=null] contralateral foot IMU, rate about x (deg/s)
 * @property {number | null} [imu_foot_contra_gyro_y_dps=null] contralateral foot IMU, rate about y (deg/s)
 * @property {number | null} [imu_foot_contra_gyro_z_dps=null] contralateral foot IMU, rate about z (deg/s)
 * @property {number | null} [imu_foot_contra_accel_x_m_s2=null] contralateral foot IMU, specific force along x (m/s^2)
 * @property {number | null} [imu_foot_contra_accel_y_m_s2=null] contralateral foot IMU, specific force along y (m/s^2)
 * @property {number | null} [imu_foot_contra_accel_z_m_s2=null] contralateral foot IMU, specific force along z (m/s^2)
 * @property {number | null} [foot_force_N=null] vertical force under the ipsilateral foot (N)
 * @property {number | null} [foot_force_contra_N=null] vertical force under the contralateral foot (N)
 * @property {boolean | null} [foot_contact=null] ipsilateral foot on the ground
 * @property {boolean | null} [foot_contact_contra=null] contralateral foot on the ground
 * @property {boolean | null} [heel_strike=null] an ipsilateral heel strike at this sample
 * @property {number | null} [motor_current_A=null] device motor current, (+) toward (+) torque (A)
 * @property {number | null} [commanded_torque_Nm=null] torque the device commands, signed as torque_Nm (N m)
 * @property {number | null} [belt_speed_m_s=null] treadmill belt speed, when known (m/s)
 * @property {number | null} [step_length_m=null] last step: forward distance between the feet at the last touchdown (m)
 * @property {number | null} [com_forward_m=null] centre of mass relative to the stance foot, forward (m)
 * @property {number | null} [com_lateral_m=null] centre of mass relative to the stance foot, (+) to the subject's right (m)
 * @property {number | null} [com_up_m=null] centre of mass relative to the stance foot, up (m)
 * @property {number | null} [com_forward_vel_m_s=null] centre-of-mass velocity relative to the stance foot, forward (m/s)
 * @property {number | null} [com_lateral_vel_m_s=null] centre-of-mass velocity relative to the stance foot, (+) to the subject's right (m/s)
 * @property {number | null} [com_up_vel_m_s=null] centre-of-mass velocity relative to the stance foot, up (m/s)
 * @property {number | null} [sent_ns=null] (0..9223372036854775807)
 */

/**
 * The estimate at one sample, as streamed to browsers and recorded (``/gait_state``).
 * @typedef {object} GaitState
 * @property {number} seq
 * @property {number} t
 * @property {number | null} phase the primary estimator's gait phase (null: no estimator drives the torque)
 * @property {number | null} phase_rate the primary estimator's, else the first healthy estimator's that estimates it (named in sources); null: not estimated
 * @property {number | null} stride_length_m the primary estimator's, else the first healthy estimator's that estimates it (named in sources); null: not estimated
 * @property {number | null} incline_deg the primary estimator's, else the first healthy estimator's that estimates it (named in sources); null: not estimated
 * @property {number} torque_Nm
 * @property {number | null} tbe_phase the timing-based estimate's phase (null: not in the stack, or failed)
 * @property {boolean} heel_strike
 * @property {boolean} backup_reset
 * @property {boolean} [fault=false] the filters were reset or the torque forced to 0 here
 * @property {number | null} foot_angle_deg
 * @property {number | null} shank_angle_deg
 * @property {number | null} thigh_angle_deg
 * @property {number | null} foot_pred_deg the primary estimator's, else the first healthy estimator's that estimates it (named in sources); null: not estimated
 * @property {number | null} shank_pred_deg the primary estimator's, else the first healthy estimator's that estimates it (named in sources); null: not estimated
 * @property {number | null} [sent_ns=null]
 * @property {number} recv_ns server wall clock when the sensor frame arrived (ns)
 * @property {Object<string, string> | null} [sources=null] which estimator each quantity comes from (phase, phase_rate, stride_length_m, incline_deg, foot_pred_deg, shank_pred_deg -> estimator name; a quantity absent is not estimated), on the first state of a stream or recording and where it changed (a primary switch, a failure); null: unchanged
 * @property {Object<string, number> | null} [torque_assumes=null] with sources: the values the torque profile takes for what the primary does not estimate (stride_length_m in m, incline_deg in deg); they drive the torque only, never shown as estimates
 */

/**
 * Sent back to a live device after each frame, and recorded (``/torque``).
 * @typedef {object} TorqueCommand
 * @property {"torque"} [type="torque"]
 * @property {number} seq
 * @property {number} t
 * @property {number} torque_Nm
 */

/**
 * Server -> browser: the gait states since the last batch (decimated as the client asked), and every
 * estimator's outputs at the same samples.
 * @typedef {object} StreamBatch
 * @property {"states"} [type="states"]
 * @property {number} session_id
 * @property {Array<GaitState>} states
 * @property {number} decimation every n-th sample is sent
 * @property {Object<string, EstimatorColumns>} [estimators] by estimator name, aligned with states
 */

/**
 * Server -> browser, about once a second: data health of the session and of this client.
 * @typedef {object} Health
 * @property {"health"} [type="health"]
 * @property {number} session_id
 * @property {number} rate_hz
 * @property {number | null} latency_ms_p50
 * @property {number | null} latency_ms_p95
 * @property {number} samples
 * @property {number} dropped_input device frames lost, out of order or over the declared rate
 * @property {number} dropped_client batches this client missed because it was slow
 * @property {number} clients
 * @property {number} [implausible=0] sensor values outside SENSOR_LIMITS, treated as missing
 * @property {number} [faults=0] filter restarts and resets, and torques forced to 0
 * @property {"ok" | "low" | "critical"} [disk="ok"] free space for the recording
 * @property {number | null} [disk_minutes=null] minutes of recording left at this session's rate before the disk guard stops it (null: unknown)
 * @property {Array<string>} [estimators] the session's estimator stack
 * @property {string | null} [primary=null] the estimator driving the torque now (null: none, the torque is 0)
 * @property {Object<string, string>} [failed_estimators] failed estimators and why
 * @property {"walking" | "standing" | "lost" | null} [tracking=null] the primary's gait tracking (estimators.lock): walking; standing still (phase held, torque 0); lost (it lost track and was reset in the last 5 s); null: no primary yet
 * @property {string} [tracking_note=""] why it lost track (when tracking is lost)
 * @property {"ok" | "fault" | null} [imu=null] the IMU front ends (estimators.imu_frontend, sessions.live.imu_events): ok; fault (a sensor has reported a problem for 0.3 s of the last second, and not yet been clear for a second); null: the stack derives no angle from raw IMUs
 * @property {string} [imu_note=""] the worst IMU problem open, naming the sensor, in the clinician's words, and how many more are open (when imu is fault)
 */

/**
 * @typedef {object} EventMessage
 * @property {"event"} [type="event"]
 * @property {Event} event
 */

/**
 * @typedef {object} SettingsMessage
 * @property {"settings"} [type="settings"]
 * @property {number} session_id
 * @property {SessionSettings} settings
 */

/**
 * @typedef {object} Hello
 * @property {"hello"} [type="hello"]
 * @property {Session} session
 * @property {Subject} subject
 * @property {number | null} source_rate_hz
 */

/**
 * Foxglove's ``foxglove.Event`` (start_time, end_time, metadata), so Foxglove lists our events.
 * @typedef {object} FoxgloveEvent
 * @property {TimeStamp} start_time
 * @property {TimeStamp} end_time
 * @property {Array<KeyValuePair>} [metadata]
 */

/**
 * What a fitted gait model was trained on; stored in every model file.
 * @typedef {object} ModelProvenance
 * @property {1} [format_version=1]
 * @property {string} gaitscope_version
 * @property {string} created_utc
 * @property {string} source 'default-cohort' or the path of the LocoHub file
 * @property {string} source_sha256 hash of the training table's signal columns
 * @property {Array<string>} subjects
 * @property {number} n_samples (>= 1)
 * @property {number} n_strides (>= 1)
 * @property {Array<number>} speeds_m_s
 * @property {Array<number>} inclines_deg
 * @property {number} fourier_order (>= 1)
 * @property {[boolean, boolean, boolean, boolean]} [outputs] which of foot, shank, heel forward, heel up were trained
 * @property {number} torque_fourier_order (>= 1)
 * @property {number | null} [cohort_seed=null]
 */

/**
 * Server -> device, instead of a torque command: why a frame was refused or dropped.
 *
 * ``kind``: ``invalid`` (the frame failed validation; ``detail`` lists the first
 * :data:`MAX_NOTICE_ERRORS` errors, without the input, and ``errors`` counts them all), ``too_large``
 * (a frame longer than :data:`MAX_FRAME_BYTES`, or with more keys than a frame has: refused unparsed;
 * ``detail`` gives its size and the limit), ``order`` (its time does not follow the last frame's),
 * ``rate`` (frames over the declared rate were dropped; ``dropped`` counts them since the last notice),
 * ``binary`` (a binary message; frames are JSON text). A notice never carries what the device sent.
 * @typedef {object} DeviceNotice
 * @property {"error"} [type="error"]
 * @property {"invalid" | "too_large" | "order" | "rate" | "binary"} kind
 * @property {string | Array<Object<string, *>>} detail
 * @property {number | null} [seq=null]
 * @property {number} [dropped=0]
 * @property {number} [errors=0] invalid: how many errors the frame had (detail lists the first few)
 */

/**
 * One estimator's outputs at one sample, recorded on its own channel (``/estimators/<name>``).
 *
 * ``values`` maps each output the estimator declares (``gaitscope.estimators.protocol.Estimator.outputs``) to its
 * value (booleans as 1.0 / 0.0), None for all of them once the estimator has failed.
 * @typedef {object} EstimatorOutputs
 * @property {number} seq
 * @property {number} t
 * @property {string} name
 * @property {Object<string, number | null>} values
 * @property {boolean} [failed=false]
 */

/**
 * Fit a subject's gait fingerprint from a recorded or uploaded trial of theirs (``POST
 * /api/subjects/{id}/fingerprints``): strides between heel strikes, thigh angle against phase and stride
 * length (belt speed x stride time when the trial records the belt, else the recorded estimate).
 * @typedef {object} CalibrationRequest
 * @property {number} trial_id (1..9223372036854775807)
 * @property {string} [model="default"]
 * @property {string} [actor="local"] set by the server to the logged-in user; ignored if sent
 * @property {string} [note=""]
 */

/**
 * Promote a personalization or roll back to the one before (``.../promote``, ``.../rollback``).
 * @typedef {object} PersonalizationChange
 * @property {string} [actor="local"] set by the server to the logged-in user; ignored if sent
 * @property {string} [reason=""]
 * @property {boolean} [confirm=false] the user confirmed the change of what drives the torque: required (else 409) while a running session of the subject has its torque follow the personalized filter (fp_ls), which takes the change live
 */

/**
 * One version of a subject's personalized gait model: a fingerprint in a model's map (seed 004).
 *
 * ``candidate`` after a calibration or an import, ``active`` once promoted (at most one per subject and
 * model: the one live sessions and review use for ``fp_ls``), ``retired`` when another was promoted.
 * @typedef {object} Personalization
 * @property {number} id
 * @property {number} subject_id
 * @property {number} version - 1, 2, ... per subject
 * @property {string} model the model whose fingerprint map this fingerprint belongs to
 * @property {Array<number>} fingerprint g_1..g_k, deg RMS each
 * @property {number} fit_rmse_avg_deg thigh-angle RMSE of the average model on the calibration walk
 * @property {number} fit_rmse_personal_deg the same with this fingerprint
 * @property {number | null} source_trial_id the calibration trial; null: imported
 * @property {number} strides_used
 * @property {number} strides_excluded
 * @property {number} seconds_used
 * @property {Object<string, number>} excluded strides left out, by reason
 * @property {string} stride_length_source 'belt speed' or the estimator whose stride length was used
 * @property {"candidate" | "active" | "retired"} state
 * @property {string} created_utc
 * @property {string} created_by
 * @property {string | null} [promoted_utc=null]
 * @property {string | null} [promoted_by=null]
 * @property {string | null} [retired_utc=null] when another was promoted or it was rolled back
 * @property {string | null} [retired_by=null]
 * @property {string} [note=""]
 */

/**
 * A training subject's least-squares fingerprint in the model's map (the fingerprint plot's cloud).
 * @typedef {object} CohortPoint
 * @property {string} code
 * @property {Array<number>} fingerprint
 */

/**
 * A subject's personalized models (``GET /api/subjects/{id}/fingerprints``).
 * @typedef {object} Fingerprints
 * @property {number} subject_id
 * @property {string} model
 * @property {number} components fingerprint components of the model's map (0: it has none)
 * @property {Array<number>} explained cumulative variance share per component of the map
 * @property {Personalization | null} active
 * @property {Array<Personalization>} versions newest first
 * @property {Array<CohortPoint>} cohort
 */

/**
 * A personalization moved between machines (``.../export``, ``.../import``): the fingerprint with the
 * model it belongs to, identified by the model's training-data hash so a map that differs is refused.
 * @typedef {object} PersonalizationExport
 * @property {"gaitscope-personalization"} [format="gaitscope-personalization"]
 * @property {1} [version=1]
 * @property {string} subject_code
 * @property {string} model
 * @property {string} model_sha256
 * @property {Array<number>} fingerprint
 * @property {number} fit_rmse_avg_deg (>= 0)
 * @property {number} fit_rmse_personal_deg (>= 0)
 * @property {number} strides_used (0..9223372036854775807)
 * @property {number} seconds_used (>= 0)
 * @property {string} created_utc
 * @property {string} [note=""]
 */

/**
 * A trial's speed-change intent over time (``GET /api/trials/{id}/intent``): the recorded outputs of
 * its ``intent`` estimator (seed 001), decimated as a trial's series, or why there are none.
 * @typedef {object} IntentSeries
 * @property {boolean} recorded the trial records the intent estimator's outputs (its stack ran it)
 * @property {Array<string>} [missing] when not recorded: the channels the intent estimator requires that the trial lacks (empty: it can run, a re-run shows it)
 * @property {Object<string, Array<number | null>>} [series] 't' (session time, s) and each output of the estimator (desired_speed_m_s, speed_m_s, ...), row for row; empty when not recorded
 */

/**
 * Start a standing calibration of a live session's IMUs (``POST /api/sessions/{id}/imu-calibration``):
 * the subject stands still, upright, for ``duration_s`` of session time.
 * @typedef {object} ImuCalibrationRequest
 * @property {number} [duration_s=5.0] (2..30)
 * @property {string} [actor="local"] set by the server to the logged-in user; ignored if sent
 * @property {string} [note=""] the posture, or anything worth keeping with it
 */

/**
 * An IMU mounting calibration of a subject in a session (also the MCAP ``/imu_calibration`` payload).
 * ``ok``: every sensor with data was accepted (stored; the subject's latest is their current one).
 * @typedef {object} ImuCalibration
 * @property {number | null} [id=null] null: refused, not stored
 * @property {number} subject_id
 * @property {number} session_id
 * @property {number | null} [trial_id=null]
 * @property {number} duration_s (>= 0)
 * @property {boolean} ok
 * @property {string} [reason=""] refused: each sensor and why
 * @property {Array<ImuSensorCalibration>} sensors
 * @property {string} [created_utc=""]
 * @property {string} [created_by="clinician"]
 * @property {string} [note=""]
 */

/**
 * A live session's IMU calibration (``GET /api/sessions/{id}/imu-calibration``).
 * @typedef {object} ImuCalibrationStatus
 * @property {number} session_id
 * @property {"idle" | "collecting" | "done" | "refused"} state
 * @property {number} progress share of the standing period collected (0..1)
 * @property {number} duration_s the period asked for (0: none yet)
 * @property {Array<string>} segments the sensors this session can calibrate (its imu_* front ends)
 * @property {ImuCalibration | null} result the last calibration's outcome (done or refused)
 * @property {ImuCalibration | null} applied what the front ends run now (this session's or the subject's)
 */

/**
 * One array of a GP model set (``estimators.gp_models.GPModelSet.to_arrays``): its shape and its values in
 * C order (JSON numbers read back to the same float64).
 * @typedef {object} GPArray
 * @property {Array<number>} shape
 * @property {Array<number>} values
 */

/**
 * One happening of the GP-EKF's learning (the MCAP ``/gp_models`` payload), logged at the session time
 * of the sample it followed (an install: of its heel strike). A review re-run installs the recorded
 * versions (``trained`` and ``kept`` carry their arrays) at the recorded ``installed`` times.
 * @typedef {object} GPModelRecord
 * @property {number} t session time (s)
 * @property {"trained" | "refused" | "failed" | "installed" | "kept" | "frozen" | "unfrozen" | "rollback"} what
 * @property {number | null} [version=null] the model version concerned (0..9223372036854775807)
 * @property {[number, number] | null} [steps=null] training window: first and last stance
 * @property {[number, number] | null} [span_s=null] training window: first and last time
 * @property {Object<string, number | null>} [rmse] held-out RMSE per channel ('hip angle': deg, 'hip velocity': deg/s; null: no sample)
 * @property {number | null} [fit_s=null] wall time the fit took (s)
 * @property {number | null} [step=null] installed: completed stances before its heel strike
 * @property {boolean} [current=false] kept: the version in force at the recording's start
 * @property {string} [reason=""] refused, failed: why; rollback: the note
 * @property {string} [actor="system"]
 * @property {Object<string, GPArray> | null} [arrays=null] trained, refused, kept: the model set
 */

/**
 * The estimation state at a trial's start (the MCAP ``/estimation_state`` payload, one per trial, at the
 * session time of the last sample before its first frame): the whole frame estimator, which a review re-run
 * restores to reproduce what ran from the first frame (:mod:`gaitscope.sessions.formats.stack_state`).
 * @typedef {object} EstimationState
 * @property {number} t session time (s) of the state: the last sample before the trial's first frame
 * @property {string} encoding how data is encoded (stack_state.ENCODING)
 * @property {Array<string>} estimators the stack it is the state of, in run order
 * @property {string} sha256 SHA-256 of the decoded data
 * @property {string} data the state, base64
 */

/**
 * A model version the GP-EKF keeps (one a rollback can reinstall).
 * @typedef {object} GPModelInfo
 * @property {number} version
 * @property {boolean} population the first model, fitted to the virtual cohort, not to this wearer
 * @property {[number, number] | null} steps its training window's first and last stance (null: population)
 * @property {[number, number] | null} span_s its training window's time span (s; null: population)
 * @property {Object<string, number | null>} rmse_deg held-out angle RMSE by joint (deg)
 * @property {Object<string, number | null>} rmse_dps held-out velocity RMSE by joint (deg/s)
 * @property {Array<number>} installed_t session times (s) of its installs (heel strikes) still kept
 */

/**
 * A version's learned joint angles over stance phase (:attr:`GPLearningState.phase`): the GP mean and its
 * band of +-2 predictive sd (the GP's variance with its noise: the spread of a measured angle), by joint.
 * @typedef {object} GPBand
 * @property {number} version
 * @property {Object<string, Array<number>>} mean_deg
 * @property {Object<string, Array<number>>} lower_deg mean - 2 sd
 * @property {Object<string, Array<number>>} upper_deg mean + 2 sd
 */

/**
 * A fit under way in the background.
 * @typedef {object} GPPendingFit
 * @property {number} version
 * @property {[number, number]} steps
 * @property {[number, number]} span_s
 * @property {number} running_s wall time since it was submitted (s)
 */

/**
 * A running session's GP-EKF learning (``GET /api/sessions/{id}/gp-learning``).
 * @typedef {object} GPLearningState
 * @property {number} session_id
 * @property {number} version the version installed now
 * @property {number | null} waiting the version installed at the next heel strike (null: none)
 * @property {boolean} rollback the waiting version is a rollback
 * @property {boolean} frozen learning is frozen: no fit, no install but a rollback
 * @property {GPPendingFit | null} pending
 * @property {number | null} [queued_s=null] a training window is ready and has waited this long (s) for the fitting worker, which the server's learning sessions share within its duty budget (null: none waiting)
 * @property {Array<GPModelInfo>} versions the versions kept, by version (rollback targets)
 * @property {string} last the last learning event's text ('' none yet)
 * @property {Array<number>} phase stance phase of the band's points, 0..1
 * @property {GPBand} current the installed version's band
 * @property {GPBand | null} requested the band of the version asked for (?version=), if any
 */

/**
 * A clinician's control of a running session's GP-EKF learning (``POST /api/sessions/{id}/gp-learning``):
 * ``freeze`` (no more fits or installs), ``unfreeze``, or ``rollback`` to a kept ``version`` (installed at the
 * next heel strike, also while frozen).
 * @typedef {object} GPLearningControl
 * @property {"freeze" | "unfreeze" | "rollback"} action
 * @property {number | null} [version=null] rollback: the kept version (0..9223372036854775807)
 * @property {string} [actor="local"] set by the server to the logged-in user; ignored if sent
 * @property {string} [reason=""]
 */

/**
 * What a stopped session gives: ``GET /api/sessions/{id}/summary`` (the same of one trial: a trial's report).
 * @typedef {object} SessionSummary
 * @property {number} session_id
 * @property {number | null} [trial_id=null] the one trial summarized; null: the whole session
 * @property {number} subject_id
 * @property {string} subject_code
 * @property {"created" | "running" | "stopped" | "failed"} state
 * @property {string} source in words: simulated walker, replay of a trial, live device, upload
 * @property {string | null} started_utc
 * @property {string | null} stopped_utc
 * @property {number} duration_s recorded time: the sum of the trials' recorded durations (s)
 * @property {number | null} [wall_s=null] the session's wall time from start to stop (s); null while it has not stopped
 * @property {Array<Trial>} trials
 * @property {number} strides
 * @property {number} [transition_strides=0] usable strides in no condition: walked while the speed or incline changed (see gaitscope.sessions.reports.summary)
 * @property {number | null} mean_speed_m_s
 * @property {number | null} mean_stride_length_m
 * @property {number | null} mean_cadence_spm strides per minute
 * @property {Array<StrideProfilePoint>} profile
 * @property {SessionSettings | null} settings_start in force when the first trial started
 * @property {SessionSettings} settings_end
 * @property {Array<SettingChangeRow>} settings_history
 * @property {Array<StrideCondition>} conditions
 * @property {DataHealthFigures} health
 * @property {Array<Event>} events
 */

/**
 * ``GET /api/sessions/{id}/summary/progress``: how far the making of a session's summary has got, for the
 * page waiting for it (a long session's recordings take seconds to read).
 * @typedef {object} SummaryProgress
 * @property {boolean} running a summary of the session is being made now
 * @property {boolean} cached the summary of the session as its trials are now is ready (kept)
 * @property {number} progress fraction of the gait states read (0..1)
 * @property {string} step what it is doing, in words
 */

/**
 * ``POST /api/sessions/{id}/exports`` (a whole session) or ``POST /api/trials/{id}/exports`` (one trial):
 * a PDF report or a CSV of the estimates.
 * @typedef {object} ExportCreate
 * @property {"pdf" | "csv"} kind
 */

/**
 * An export being made (``GET /api/exports/{id}``); its file is ``GET /api/exports/{id}/file`` once done.
 * @typedef {object} ExportJob
 * @property {string} id
 * @property {number} session_id
 * @property {number | null} [trial_id=null] the one trial exported; null: the whole session
 * @property {"pdf" | "csv"} kind
 * @property {"running" | "done" | "failed"} state
 * @property {number} progress (0..1)
 * @property {string} step what it is doing, in words
 * @property {string} filename
 * @property {string} [error=""]
 */

/**
 * Two or more re-runs of one trial compared (``POST /api/trials/{id}/compare``); the first is the reference.
 * @typedef {object} CompareRequest
 * @property {Array<ComparedRunSpec>} runs
 */

/**
 * The answer of ``POST /api/trials/{id}/compare``.
 * @typedef {object} Comparison
 * @property {Array<number>} t session time (s) of the rows, decimated keeping every series' extremes
 * @property {Array<number>} stride_pct - 0-100 % of the stride, the x of the runs' mean strides
 * @property {string | null} ground_truth where the truth the errors are against comes from; null: none known
 * @property {Array<ComparedRun>} runs
 */

/**
 * A note added in review at a time, or over a span, of a trial (``POST /api/trials/{id}/annotations``).
 * @typedef {object} ReviewAnnotationCreate
 * @property {number} t session time (s) it is at (or starts at) (0..1e+09)
 * @property {number | null} [t_end=null] end of its span (s); null: a single time (0..1e+09)
 * @property {string} text
 * @property {string} [actor="local"] set by the server to the logged-in user; ignored if sent
 */

/**
 * A note of a trial: added in review, or taken live during its recording (an ``annotation`` event of the
 * session logged while the trial recorded: its ``id`` is the event's, and it is not deleted from review).
 * @typedef {object} ReviewAnnotation
 * @property {number} t session time (s) it is at (or starts at) (0..1e+09)
 * @property {number | null} [t_end=null] end of its span (s); null: a single time (0..1e+09)
 * @property {string} text
 * @property {string} [actor="local"] set by the server to the logged-in user; ignored if sent
 * @property {number} id
 * @property {number} trial_id
 * @property {string} created_utc
 * @property {"review" | "live"} [source="review"] review: added in review (its author may delete it); live: taken live
 */

/**
 * Undo the session's last applied settings change (``POST /api/sessions/{id}/settings/undo``): its fields go
 * back to their values before it, within the same bounds and rate limits as any change, logged as a change.
 * @typedef {object} SettingsUndo
 * @property {string} [actor="local"] set by the server to the logged-in user; ignored if sent
 * @property {boolean} [confirm=false] as SettingsChange.confirm: an undo that can raise the torque on the person needs it
 */

/**
 * An account (never its password hash).
 * @typedef {object} User
 * @property {number} id
 * @property {string} name
 * @property {"admin" | "clinician" | "experimenter" | "viewer"} role
 * @property {boolean} [disabled=false]
 * @property {string} created_utc
 * @property {string} created_by
 * @property {string | null} [last_login_utc=null]
 * @property {number} [failed_logins=0] failed logins at this name since the last good one
 * @property {string | null} [locked_until_utc=null] addresses that failed at this name wait until then (an address that has not failed never waits)
 */

/**
 * @typedef {object} UserCreate
 * @property {string} name
 * @property {"admin" | "clinician" | "experimenter" | "viewer"} role
 * @property {string} password
 */

/**
 * An admin's change of an account; fields left out keep their value.
 * @typedef {object} UserChange
 * @property {"admin" | "clinician" | "experimenter" | "viewer" | null} [role=null]
 * @property {boolean | null} [disabled=null]
 * @property {boolean} [unlock=false] end a lockout now and reset the failed-login count
 * @property {string | null} [password=null] set a new password (a reset)
 */

/**
 * @typedef {object} LoginRequest
 * @property {string} name
 * @property {string} password
 */

/**
 * @typedef {object} PasswordChange
 * @property {string} current
 * @property {string} new
 */

/**
 * Who the server takes the caller to be (``GET /api/auth/me``).
 * @typedef {object} Me
 * @property {string} name
 * @property {"admin" | "clinician" | "experimenter" | "viewer"} role
 * @property {boolean} accounts accounts are on: a login is needed; off: loopback only, everyone is 'local'
 * @property {Array<"read" | "run" | "annotate" | "upload" | "assist" | "assist_within_limits" | "promote" | "set_limits" | "admin">} permissions
 * @property {string | null} [csrf_token=null] send it as the X-CSRF-Token header with every state-changing request
 */

/**
 * A device's credential for one session's ``/ws/devices/{id}``; ``token`` is shown once, when issued.
 * @typedef {object} DeviceToken
 * @property {number} id
 * @property {number} session_id
 * @property {string} prefix its first characters, to tell tokens apart (the token itself is never stored)
 * @property {string} created_utc
 * @property {string} created_by
 * @property {string | null} [revoked_utc=null]
 * @property {string | null} [revoked_by=null]
 * @property {string | null} [token=null] the token: present only in the answer that issued it
 */

/**
 * The most assistance an experimenter may set for a subject, set by a clinician. An experimenter may
 * change torque gain, torque bound and intent boost only up to these (and lower them freely); noise scales
 * are estimator tuning, not assistance, and are theirs to change.
 * @typedef {object} AssistanceLimits
 * @property {number} [torque_gain=1.0] (0..3)
 * @property {number} [max_torque_Nm=30.0] (0..80)
 * @property {number} [intent_gain_boost=0.0] (0..0.3)
 */

/**
 * @typedef {object} SubjectLimits
 * @property {number} [torque_gain=1.0] (0..3)
 * @property {number} [max_torque_Nm=30.0] (0..80)
 * @property {number} [intent_gain_boost=0.0] (0..0.3)
 * @property {number} subject_id
 * @property {string} set_by
 * @property {string} set_utc
 */

/**
 * One entry of the audit trail (``gaitscope.sessions.audit``): who did what to what, when, and how it ended.
 *
 * ``before`` and ``after`` are JSON text exactly as hashed (null: nothing). ``hash`` is the SHA-256 of the
 * entry's canonical JSON including ``prev_hash``, the previous entry's ``hash`` (``sessions/audit/log.py``
 * says how, so that anyone can re-check the chain with other tools).
 * @typedef {object} AuditEntry
 * @property {number} id
 * @property {number} seq - 1, 2, 3... without gaps: a missing number is a deleted entry (>= 1)
 * @property {string} time_utc ISO-8601 UTC, to the millisecond
 * @property {string} user
 * @property {string} role the user's role then; 'none' for a caller nobody knows
 * @property {string} action what was asked, dotted ('session.start', 'settings.change', 'login')
 * @property {string} target what it was done to ('session 7', a path)
 * @property {string | null} [before=null] JSON text: the state before the change
 * @property {string | null} [after=null] JSON text: the state asked for
 * @property {"requested" | "done" | "failed" | "refused"} outcome
 * @property {string} [detail=""]
 * @property {string} prev_hash
 * @property {string} hash
 * @property {string | null} [mac=null] HMAC-SHA256 of ``hash`` under the audit key (null: written before the trail was keyed)
 */

/**
 * Filters of ``GET /api/audit`` and its CSV: all given ones must hold; newest entries first.
 * @typedef {object} AuditQuery
 * @property {string | null} [user=null] exactly this user
 * @property {string | null} [action=null] actions starting so
 * @property {"requested" | "done" | "failed" | "refused" | null} [outcome=null]
 * @property {string | null} [target=null] targets starting so
 * @property {string | null} [since=null] from this time on (ISO-8601, UTC if no zone)
 * @property {string | null} [until=null] before this time (exclusive)
 * @property {number} [limit=100] (1..1000)
 * @property {number} [offset=0] (0..9223372036854775807)
 */

/**
 * What ``gaitscope audit verify`` (and ``GET /api/audit/verify``) found.
 * @typedef {object} AuditVerification
 * @property {boolean} ok
 * @property {number} entries entries checked (all of them when ok)
 * @property {number | null} [first_bad_seq=null] where the chain first breaks
 * @property {string | null} [problem=null] why, in words ('hash mismatch at seq 17 ...')
 * @property {string | null} [last_hash=null] the newest entry's hash: note it elsewhere to detect a cut-off tail later
 * @property {number | null} [keyed_from=null] the first entry with a MAC; those before it (written before the trail was keyed) are checked by the SHA-256 chain only. Null: no keyed entry
 * @property {number | null} [checkpoint_seq=null] the checkpoint checked against: no entry up to this seq was cut or rewritten
 */

/**
 * The ``detail`` of the 409 to a settings change or undo that can raise the torque on the person and was not
 * confirmed (``reason="confirm"``: resend it with ``confirm: true`` once the user agreed to the peaks shown) or
 * came too soon after the last such change (``reason="too_soon"``: it may be made ``retry_after_s`` later).
 * The peaks are the torque the settings command over a stride at the session's gait state
 * (``gaitscope.sessions.peak_torque``), intent boost at its largest.
 * @typedef {object} TorqueRaiseRefused
 * @property {string} message
 * @property {"confirm" | "too_soon"} reason
 * @property {Array<string>} fields the settings of the change that can raise the torque
 * @property {number} peak_before_Nm peak torque over a stride with the settings now (>= 0)
 * @property {number} peak_after_Nm peak torque over a stride with the change made (>= 0)
 * @property {number} retry_after_s how long until it may be made (0: now, with confirm) (>= 0)
 */

/**
 * ``POST /api/sessions/{id}/settings/check``: what a settings change would do to the torque, changing nothing,
 * for a client to ask its user before it sends the change (which is judged again when sent).
 * @typedef {object} TorqueCheck
 * @property {Array<string>} fields the settings of the change that can raise the torque ([]: it asks nothing)
 * @property {number} peak_before_Nm peak torque over a stride with the settings now (>= 0)
 * @property {number} peak_after_Nm peak torque over a stride with the change made (>= 0)
 * @property {number} retry_after_s how long until a change that can raise the torque may be made (>= 0)
 */

/**
 * A registered estimator as ``GET /api/estimators`` describes it (its descriptor in
 * ``gaitscope.sessions.registry.DESCRIPTORS``), for choosing a session's stack (``SessionSettings.estimators``
 * and ``primary``), with what it costs on this server. Named so, not ``EstimatorInfo``: that is ``wire.js``'s
 * type of its ``ESTIMATORS`` table.
 * @typedef {object} RegisteredEstimator
 * @property {string} name its machine name, as SessionSettings.estimators and primary name it
 * @property {string} label its name on screen
 * @property {string} purpose what it is for, in one line
 * @property {string | null} paper the paper it implements (its seed); null: none, gaitscope's own
 * @property {Array<string>} inputs the channels it requires (SensorFrame field names)
 * @property {Array<string>} inputs_any it needs at least one of these (empty: no such rule)
 * @property {Array<string>} optional_inputs channels it uses when the source sends them
 * @property {boolean} phase it estimates a phase (of the gait cycle or of stance): the torque may follow it
 * @property {boolean} opt_in a session runs it only when named: the default stack leaves it out
 * @property {boolean} derives a front end deriving channels: the default stack leaves it out when the source sends them
 * @property {number | null} cost_us its median time per sample on this server (microseconds), measured at start-up over a synthetic walk; null: not measured (the model cannot build it)
 */

/**
 * One re-run's figures, its time series (on the comparison's ``t``) and its mean stride.
 * @typedef {object} ComparedRun
 * @property {string} name
 * @property {RunFigures} figures
 * @property {Array<number | null>} torque_Nm torque command, row for row with the comparison's t
 * @property {Array<number | null>} phase_pct phase (% of the gait cycle), row for row with t
 * @property {Array<number | null>} torque_diff_Nm this run's torque minus the first run's
 * @property {Array<number | null>} phase_diff_pct this run's phase minus the first run's, wrapped to ±50 %
 * @property {Array<number | null>} stride_torque_mean_Nm mean torque per % of the stride (stride_pct)
 * @property {Array<number | null>} stride_torque_sd_Nm its standard deviation across strides
 * @property {string} [start=""] how its estimators began: resumed from the estimation state recorded at the trial's start (a run as recorded: what ran, exactly), or fresh filters and why (the re-run's start)
 */

/**
 * One re-run of an A/B comparison: its name (the user's) and how it runs (as :class:`RerunRequest`).
 * @typedef {object} ComparedRunSpec
 * @property {string} name the name the user gives it ('A', 'gain 1.3')
 * @property {SessionSettings | null} [settings=null] null: the recorded settings and their changes (what ran); else held over the trial
 * @property {Array<string> | null} [estimators=null] null: the recorded stack
 */

/**
 * How good the session's data is, over every recorded trial.
 * @typedef {object} DataHealthFigures
 * @property {number} samples
 * @property {number} recorded_s
 * @property {number | null} rate_hz median sample rate; null without samples
 * @property {number} gaps breaks in the data longer than three sample periods
 * @property {number} longest_gap_s
 * @property {number} missing_percent samples without a measured thigh, shank or foot angle, in %
 * @property {number} faults samples at which the filters were reset or the torque forced to 0
 * @property {number} backup_resets
 * @property {number} trials_recovered
 * @property {number} trials_damaged
 */

/**
 * A live device that connects to ``/ws/devices/{session_id}`` and pushes sensor frames.
 *
 * ``rate_hz`` is the device's declared sample rate, at most :data:`MAX_DEVICE_RATE_HZ`: the server
 * takes up to ``1.25 x rate_hz`` frames per second (with a burst of two seconds' worth) and drops the
 * rest, counted and reported to the device, so that a flooding device cannot starve the other sessions.
 * A session stored before that limit with a higher rate reads as the limit (its row is unchanged).
 * @typedef {object} DeviceSource
 * @property {"device"} [kind="device"]
 * @property {number} [rate_hz=200.0] declared sample rate (Hz), at most 1000 (1..1000)
 * @property {Array<string> | null} [channels=null] the SensorFrame channels the device sends: the session's stack is chosen for them, and an estimator asked for that needs another is refused at start; null: unknown, every estimator may run
 */

/**
 * One estimator's outputs over a :class:`StreamBatch`: one column per output, row for row with the
 * batch's states (None where it had failed).
 * @typedef {object} EstimatorColumns
 * @property {boolean} failed it has failed (its outputs are no longer computed)
 * @property {Object<string, Array<number | null>>} columns
 */

/**
 * One sensor's result (``gaitscope.estimators.imu_calibration.SensorCalibration``): the offsets its front end
 * ``imu_<segment>`` takes, or why it was refused.
 * @typedef {object} ImuSensorCalibration
 * @property {string} segment foot, shank, thigh, foot_contra, ...
 * @property {boolean} ok
 * @property {string} [reason=""] empty when accepted
 * @property {number} pitch_offset_deg (-180..180)
 * @property {[number, number, number]} gyro_bias_dps x, y, z (deg/s)
 * @property {number | null} gyro_motion_dps largest gyro deviation from its mean (null: too few samples)
 * @property {number | null} accel_sd largest per-axis accelerometer sd (m/s^2)
 */

/**
 * @typedef {object} KeyValuePair
 * @property {string} key
 * @property {string} value
 */

/**
 * A Lab Streaming Layer stream (an IMU, EMG or motion capture outlet on the lab's network), resolved by
 * ``name`` and/or ``type`` (and ``source_id`` if given) when the session starts
 * (:mod:`gaitscope.sessions.live.lsl_source`).
 *
 * ``mapping`` gives each stream channel used its SensorFrame channel: by index (``"0"``, ``"1"``, ...) or by
 * the label in the stream's XML description. Null: the mapping saved for the stream's rig (its name, type,
 * channel count and source id), which a session given one saves. Frame time is the sample's LSL time on this
 * machine's clock (``time_correction()`` added), from 0 at the first sample.
 * @typedef {object} LslSource
 * @property {"lsl"} [kind="lsl"]
 * @property {string | null} [name=null] the stream's name (null: any)
 * @property {string | null} [type=null] the stream's type, e.g. IMU (null: any)
 * @property {string | null} [source_id=null] the stream's source id (null: any)
 * @property {Object<string, string> | null} [mapping=null] stream channel (index from 0, or label) -> SensorFrame channel; null: the one saved for the rig
 * @property {number} [resolve_timeout_s=2.0] how long to look for the stream (0.1..30)
 * @property {number} [quiet_s=2.0] no sample for this long: the stream is quiet (the session holds) (0.1..60)
 */

/**
 * @typedef {object} ProtocolStep
 * @property {number} speed_m_s (0.3..2)
 * @property {number} incline_deg (-15..15)
 * @property {number} strides (1..2000)
 */

/**
 * A stored trial (recorded, or uploaded MCAP / replay CSV / LocoHub file) played back.
 * @typedef {object} ReplaySource
 * @property {"replay"} [kind="replay"]
 * @property {number} trial_id (1..9223372036854775807)
 * @property {number} [speed=1.0] - 1x real time or faster (1..50)
 * @property {boolean} [loop=false]
 */

/**
 * Figures of one re-run over the compared window; errors only when the trial's ground truth is known.
 * @typedef {object} RunFigures
 * @property {number} strides complete strides (heel strike to heel strike, 0.3-4 s)
 * @property {number | null} peak_torque_Nm mean over the strides of each stride's peak torque command
 * @property {number | null} mean_phase_rate_1_s mean estimated phase rate (strides per second)
 * @property {number | null} mean_stride_length_m mean estimated stride length
 * @property {number | null} [phase_rmse_pct=null] RMS phase error against the truth (% of a cycle)
 * @property {number | null} [phase_rate_rmse_1_s=null] RMS phase-rate error against the truth
 * @property {number | null} [stride_length_rmse_m=null] RMS stride-length error against the truth
 * @property {number | null} [incline_rmse_deg=null] RMS incline error against the truth
 */

/**
 * One setting change, in words a clinician reads.
 * @typedef {object} SettingChangeRow
 * @property {number} t
 * @property {string} wall_utc
 * @property {string} text e.g. "Torque gain 1.00 -> 1.30, by clinician"
 */

/**
 * A virtual-cohort subject walking a protocol through simulated sensors, in real time.
 * @typedef {object} SimulatedSource
 * @property {"simulated"} [kind="simulated"]
 * @property {Array<ProtocolStep>} [protocol]
 * @property {number} [rate_hz=200.0] (20..1000)
 * @property {number} [cohort_subject=0] (0..9)
 * @property {boolean} [loop=true]
 * @property {number} [seed=7] (0..9223372036854775807)
 */

/**
 * The strides walked at one condition (speed and incline, binned), as curves over the stride (0-100 %).
 *
 * ``mean`` and every row of ``strides`` have one value per point of ``percent`` (None where the signal was
 * missing); ``strides`` keeps at most :data:`SUMMARY_MAX_OVERLAY` of them (evenly spread).
 * @typedef {object} StrideCondition
 * @property {string} label
 * @property {number} speed_m_s
 * @property {number} incline_deg
 * @property {number} strides
 * @property {Array<number>} percent
 * @property {Object<string, Array<number | null>>} signals signal -> mean curve
 * @property {Object<string, Array<Array<number | null>>>} overlays signal -> a few single strides' curves
 */

/**
 * One stride of a session: when it started, its speed and incline (the speed and incline profile).
 * @typedef {object} StrideProfilePoint
 * @property {number} trial_id
 * @property {number} t session time (s) of the heel strike that starts it
 * @property {number} duration_s
 * @property {number} speed_m_s estimated stride length over the stride's duration
 * @property {number} incline_deg mean estimated incline over the stride
 * @property {boolean} [after_gap=false] the first stride of its trial, or one after time not recorded or not usable: a profile's line breaks before it rather than bridge the gap
 */

/**
 * @typedef {object} TimeStamp
 * @property {number} sec
 * @property {number} nsec
 */

/**
 * A log uploaded for review (MCAP, replay CSV or LocoHub); its session holds the imported trial.
 * @typedef {object} UploadSource
 * @property {"upload"} [kind="upload"]
 * @property {string} filename
 * @property {string | null} [sha256=null] the file's SHA-256 (null: uploaded before it was kept)
 */

/**
 * A message of a session's stream to the browser (`/ws/sessions/{id}`), told apart by its `type`.
 * @typedef {Hello | StreamBatch | Health | EventMessage | SettingsMessage} BrowserMessage
 */

/** Freezes an object and every object in it. */
function deepFreeze(o) {
  for (const v of Object.values(o)) if (v && typeof v === "object") deepFreeze(v);
  return Object.freeze(o);
}

/**
 * Bounds of every clinician-adjustable setting (`SETTING_LIMITS`): minimum, maximum, and the largest
 * change per second (the server also spaces two changes of a field by `step / rate` seconds).
 * @type {Readonly<Record<string, {min: number, max: number, rate: number}>>}
 */
export const SETTING_LIMITS = deepFreeze({
  torque_gain: { min: 0.0, max: 3.0, rate: 0.5 },
  max_torque_Nm: { min: 0.0, max: 80.0, rate: 10.0 },
  measurement_noise_scale: { min: 0.1, max: 10.0, rate: 5.0 },
  process_noise_scale: { min: 0.1, max: 10.0, rate: 5.0 },
  intent_gain_boost: { min: 0.0, max: 0.3, rate: 0.1 },
});

/**
 * The rule for a settings change that can raise the torque (`gaitscope.sessions.live.torque_rule`): the
 * settings whose rise (or, the primary, whose switch) asks for a confirmation, and the least time between
 * two such changes (`TORQUE_RAISE_INTERVAL_S`). Lowering never asks and is never held back.
 * @type {Readonly<{interval_s: number, raising: Array<string>}>}
 */
export const TORQUE_RULE = deepFreeze({ interval_s: 3.0, raising: ["torque_gain", "max_torque_Nm", "intent_gain_boost", "primary"] });

/**
 * Physically plausible range of each sensor channel (`SENSOR_LIMITS`); a value outside it is treated
 * as missing for that sample.
 * @type {Readonly<Record<string, {min: number, max: number}>>}
 */
export const SENSOR_LIMITS = deepFreeze({
  foot_angle_deg: { min: -180.0, max: 180.0 },
  foot_vel_dps: { min: -4000.0, max: 4000.0 },
  shank_angle_deg: { min: -180.0, max: 180.0 },
  shank_vel_dps: { min: -4000.0, max: 4000.0 },
  heel_forward_m: { min: -3.0, max: 3.0 },
  heel_up_m: { min: -3.0, max: 3.0 },
  thigh_angle_deg: { min: -180.0, max: 180.0 },
  thigh_vel_dps: { min: -4000.0, max: 4000.0 },
  foot_angle_contra_deg: { min: -180.0, max: 180.0 },
  foot_vel_contra_dps: { min: -4000.0, max: 4000.0 },
  shank_angle_contra_deg: { min: -180.0, max: 180.0 },
  shank_vel_contra_dps: { min: -4000.0, max: 4000.0 },
  thigh_angle_contra_deg: { min: -180.0, max: 180.0 },
  thigh_vel_contra_dps: { min: -4000.0, max: 4000.0 },
  hip_angle_deg: { min: -180.0, max: 180.0 },
  knee_angle_deg: { min: -180.0, max: 180.0 },
  ankle_angle_deg: { min: -180.0, max: 180.0 },
  hip_angle_contra_deg: { min: -180.0, max: 180.0 },
  knee_angle_contra_deg: { min: -180.0, max: 180.0 },
  ankle_angle_contra_deg: { min: -180.0, max: 180.0 },
  imu_pelvis_gyro_x_dps: { min: -4000.0, max: 4000.0 },
  imu_pelvis_gyro_y_dps: { min: -4000.0, max: 4000.0 },
  imu_pelvis_gyro_z_dps: { min: -4000.0, max: 4000.0 },
  imu_pelvis_accel_x_m_s2: { min: -157.0, max: 157.0 },
  imu_pelvis_accel_y_m_s2: { min: -157.0, max: 157.0 },
  imu_pelvis_accel_z_m_s2: { min: -157.0, max: 157.0 },
  imu_thigh_gyro_x_dps: { min: -4000.0, max: 4000.0 },
  imu_thigh_gyro_y_dps: { min: -4000.0, max: 4000.0 },
  imu_thigh_gyro_z_dps: { min: -4000.0, max: 4000.0 },
  imu_thigh_accel_x_m_s2: { min: -157.0, max: 157.0 },
  imu_thigh_accel_y_m_s2: { min: -157.0, max: 157.0 },
  imu_thigh_accel_z_m_s2: { min: -157.0, max: 157.0 },
  imu_shank_gyro_x_dps: { min: -4000.0, max: 4000.0 },
  imu_shank_gyro_y_dps: { min: -4000.0, max: 4000.0 },
  imu_shank_gyro_z_dps: { min: -4000.0, max: 4000.0 },
  imu_shank_accel_x_m_s2: { min: -157.0, max: 157.0 },
  imu_shank_accel_y_m_s2: { min: -157.0, max: 157.0 },
  imu_shank_accel_z_m_s2: { min: -157.0, max: 157.0 },
  imu_foot_gyro_x_dps: { min: -4000.0, max: 4000.0 },
  imu_foot_gyro_y_dps: { min: -4000.0, max: 4000.0 },
  imu_foot_gyro_z_dps: { min: -4000.0, max: 4000.0 },
  imu_foot_accel_x_m_s2: { min: -157.0, max: 157.0 },
  imu_foot_accel_y_m_s2: { min: -157.0, max: 157.0 },
  imu_foot_accel_z_m_s2: { min: -157.0, max: 157.0 },
  imu_thigh_contra_gyro_x_dps: { min: -4000.0, max: 4000.0 },
  imu_thigh_contra_gyro_y_dps: { min: -4000.0, max: 4000.0 },
  imu_thigh_contra_gyro_z_dps: { min: -4000.0, max: 4000.0 },
  imu_thigh_contra_accel_x_m_s2: { min: -157.0, max: 157.0 },
  imu_thigh_contra_accel_y_m_s2: { min: -157.0, max: 157.0 },
  imu_thigh_contra_accel_z_m_s2: { min: -157.0, max: 157.0 },
  imu_shank_contra_gyro_x_dps: { min: -4000.0, max: 4000.0 },
  imu_shank_contra_gyro_y_dps: { min: -4000.0, max: 4000.0 },
  imu_shank_contra_gyro_z_dps: { min: -4000.0, max: 4000.0 },
  imu_shank_contra_accel_x_m_s2: { min: -157.0, max: 157.0 },
  imu_shank_contra_accel_y_m_s2: { min: -157.0, max: 157.0 },
  imu_shank_contra_accel_z_m_s2: { min: -157.0, max: 157.0 },
  imu_foot_contra_gyro_x_dps: { min: -4000.0, max: 4000.0 },
  imu_foot_contra_gyro_y_dps: { min: -4000.0, max: 4000.0 },
  imu_foot_contra_gyro_z_dps: { min: -4000.0, max: 4000.0 },
  imu_foot_contra_accel_x_m_s2: { min: -157.0, max: 157.0 },
  imu_foot_contra_accel_y_m_s2: { min: -157.0, max: 157.0 },
  imu_foot_contra_accel_z_m_s2: { min: -157.0, max: 157.0 },
  foot_force_N: { min: 0.0, max: 5000.0 },
  foot_force_contra_N: { min: 0.0, max: 5000.0 },
  motor_current_A: { min: -60.0, max: 60.0 },
  commanded_torque_Nm: { min: -200.0, max: 200.0 },
  belt_speed_m_s: { min: 0.0, max: 5.0 },
  step_length_m: { min: 0.0, max: 3.0 },
  com_forward_m: { min: -3.0, max: 3.0 },
  com_lateral_m: { min: -3.0, max: 3.0 },
  com_up_m: { min: -3.0, max: 3.0 },
  com_forward_vel_m_s: { min: -10.0, max: 10.0 },
  com_lateral_vel_m_s: { min: -10.0, max: 10.0 },
  com_up_vel_m_s: { min: -10.0, max: 10.0 },
});

/**
 * The name on screen and the unit ("": none) of every field a setting event may change
 * (`SETTING_NAMES`): the settings, the primary estimator, the models.
 * @type {Readonly<Record<string, {name: string, unit: string}>>}
 */
export const SETTING_NAMES = deepFreeze({
  torque_gain: { name: "Torque gain", unit: "\u00d7" },
  max_torque_Nm: { name: "Maximum torque", unit: "N\u00b7m" },
  measurement_noise_scale: { name: "Measurement-noise scale", unit: "\u00d7" },
  process_noise_scale: { name: "Process-noise scale", unit: "\u00d7" },
  intent_gain_boost: { name: "Intent gain boost", unit: "fraction of gain" },
  primary: { name: "Torque follows", unit: "" },
  model: { name: "Gait model", unit: "" },
  imu_calibration: { name: "IMU calibration", unit: "" },
});

/**
 * Each gait-state quantity's name on screen and unit (`estimators/descriptor.py` `QUANTITY_NAMES`;
 * a phase in % of its cycle).
 * @type {Readonly<Record<string, {name: string, unit: string}>>}
 */
export const QUANTITY_NAMES = deepFreeze({
  phase: { name: "Gait phase", unit: "%" },
  phase_rate: { name: "Phase rate", unit: "1/s" },
  stance_phase: { name: "Stance phase", unit: "%" },
  stance_phase_rate: { name: "Stance-phase rate", unit: "1/s" },
  stride_length: { name: "Stride length", unit: "m" },
  incline: { name: "Incline", unit: "deg" },
  speed: { name: "Speed", unit: "m/s" },
  desired_speed: { name: "Desired speed", unit: "m/s" },
  knee_angle: { name: "Knee angle", unit: "deg" },
});

/**
 * A session's settings when none are given (`SessionSettings()`).
 * @type {Readonly<SessionSettings>}
 */
export const DEFAULT_SETTINGS = deepFreeze({
  torque_gain: 1.0,
  max_torque_Nm: 30.0,
  measurement_noise_scale: 1.0,
  process_noise_scale: 1.0,
  intent_gain_boost: 0.0,
  model: "default",
  primary: "phase_ekf",
  estimators: null,
  lsl_outlet: false,
});

/**
 * A plot a view draws of an estimator's outputs (`PlotHint`): its key in the view, title, y label
 * and the outputs it draws, a line each.
 * @typedef {object} PlotHint
 * @property {string} key
 * @property {string} title
 * @property {string} y_label
 * @property {Array<string>} outputs
 */

/**
 * A registered estimator as its descriptor states it (`estimators/descriptor.py`): its name on
 * screen, its outputs (name: unit; a re-run's columns are `<name>.<output>`), the gait-state
 * quantity of some of them (`phase`, `stance_phase`, `stride_length`, ...), the plots a view draws
 * of them, whether a session runs it only when named and whether it is a front end deriving
 * channels, the name on screen of a model it learns online (setting events whose field is the
 * estimator's name carry that model's versions) and its gait-fingerprint variant.
 * @typedef {object} EstimatorInfo
 * @property {string} label
 * @property {Record<string, string>} outputs
 * @property {Record<string, string>} quantities
 * @property {Array<PlotHint>} plots
 * @property {boolean} opt_in
 * @property {boolean} derives
 * @property {string | null} learned_model
 * @property {"average" | "personal" | "online" | null} fingerprint
 */

/**
 * Every registered estimator (`sessions.registry.DESCRIPTORS`), in the order a stack runs them.
 * @type {Readonly<Record<string, EstimatorInfo>>}
 */
export const ESTIMATORS = deepFreeze({
  imu_foot: {
    label: "IMU front end (foot)",
    outputs: { foot_angle_deg: "deg", foot_vel_dps: "deg/s", imu_code: "code", foot_flat: "bool", toe_off: "bool" },
    quantities: {},
    plots: [],
    opt_in: false,
    derives: true,
    learned_model: null,
    fingerprint: null,
  },
  imu_shank: {
    label: "IMU front end (shank)",
    outputs: { shank_angle_deg: "deg", shank_vel_dps: "deg/s", imu_code: "code" },
    quantities: {},
    plots: [],
    opt_in: false,
    derives: true,
    learned_model: null,
    fingerprint: null,
  },
  imu_thigh: {
    label: "IMU front end (thigh)",
    outputs: { thigh_angle_deg: "deg", thigh_vel_dps: "deg/s", imu_code: "code" },
    quantities: {},
    plots: [],
    opt_in: false,
    derives: true,
    learned_model: null,
    fingerprint: null,
  },
  imu_foot_contra: {
    label: "IMU front end (foot contra)",
    outputs: {
      foot_angle_contra_deg: "deg",
      foot_vel_contra_dps: "deg/s",
      imu_code: "code",
      foot_flat: "bool",
      toe_off: "bool",
    },
    quantities: {},
    plots: [],
    opt_in: false,
    derives: true,
    learned_model: null,
    fingerprint: null,
  },
  imu_shank_contra: {
    label: "IMU front end (shank contra)",
    outputs: { shank_angle_contra_deg: "deg", shank_vel_contra_dps: "deg/s", imu_code: "code" },
    quantities: {},
    plots: [],
    opt_in: false,
    derives: true,
    learned_model: null,
    fingerprint: null,
  },
  imu_thigh_contra: {
    label: "IMU front end (thigh contra)",
    outputs: { thigh_angle_contra_deg: "deg", thigh_vel_contra_dps: "deg/s", imu_code: "code" },
    quantities: {},
    plots: [],
    opt_in: false,
    derives: true,
    learned_model: null,
    fingerprint: null,
  },
  hs_detector: {
    label: "Heel-strike detector",
    outputs: { heel_strike: "bool" },
    quantities: {},
    plots: [],
    opt_in: false,
    derives: false,
    learned_model: null,
    fingerprint: null,
  },
  phase_ekf: {
    label: "Phase EKF (seed 000)",
    outputs: {
      phase: "1",
      phase_rate: "1/s",
      stride_length_m: "m",
      incline_deg: "deg",
      heel_strike: "bool",
      backup_reset: "bool",
      fault: "code",
      foot_pred_deg: "deg",
      shank_pred_deg: "deg",
      standing: "1",
    },
    quantities: { phase: "phase", phase_rate: "phase_rate", stride_length_m: "stride_length", incline_deg: "incline" },
    plots: [],
    opt_in: false,
    derives: false,
    learned_model: null,
    fingerprint: null,
  },
  tbe: {
    label: "Timing-based estimate",
    outputs: { phase: "1", phase_rate: "1/s" },
    quantities: { phase: "phase", phase_rate: "phase_rate" },
    plots: [],
    opt_in: false,
    derives: false,
    learned_model: null,
    fingerprint: null,
  },
  hs_backup: {
    label: "Heel-strike backup",
    outputs: { phase: "1", phase_rate: "1/s", stride_length_m: "m", incline_deg: "deg" },
    quantities: { phase: "phase", phase_rate: "phase_rate", stride_length_m: "stride_length", incline_deg: "incline" },
    plots: [],
    opt_in: true,
    derives: false,
    learned_model: null,
    fingerprint: null,
  },
  fp_avg: {
    label: "Average thigh model (seed 004)",
    outputs: { phase: "1", phase_rate: "1/s", stride_length_m: "m", thigh_pred_deg: "deg" },
    quantities: { phase: "phase", phase_rate: "phase_rate", stride_length_m: "stride_length" },
    plots: [],
    opt_in: false,
    derives: false,
    learned_model: null,
    fingerprint: "average",
  },
  fp_ls: {
    label: "Personalized thigh model (seed 004 LS-GF)",
    outputs: { phase: "1", phase_rate: "1/s", stride_length_m: "m", thigh_pred_deg: "deg" },
    quantities: { phase: "phase", phase_rate: "phase_rate", stride_length_m: "stride_length" },
    plots: [],
    opt_in: false,
    derives: false,
    learned_model: null,
    fingerprint: "personal",
  },
  fp_gf: {
    label: "Online fingerprint EKF (seed 004 GF)",
    outputs: {
      phase: "1",
      phase_rate: "1/s",
      stride_length_m: "m",
      thigh_pred_deg: "deg",
      g1: "deg",
      g2: "deg",
      g3: "deg",
    },
    quantities: { phase: "phase", phase_rate: "phase_rate", stride_length_m: "stride_length" },
    plots: [],
    opt_in: false,
    derives: false,
    learned_model: null,
    fingerprint: "online",
  },
  com_kin: {
    label: "Centre of mass from leg kinematics (seed 001)",
    outputs: { com_forward_m: "m", com_up_m: "m", com_forward_vel_m_s: "m/s", com_up_vel_m_s: "m/s" },
    quantities: {},
    plots: [],
    opt_in: false,
    derives: true,
    learned_model: null,
    fingerprint: null,
  },
  intent: {
    label: "Speed-change intent (seed 001)",
    outputs: {
      desired_speed_m_s: "m/s",
      intent_m_s: "m/s",
      intent_code: "code",
      intent_confidence: "1",
      speed_m_s: "m/s",
    },
    quantities: { desired_speed_m_s: "desired_speed", speed_m_s: "speed" },
    plots: [{
      key: "intent",
      title: "Speed-change intent: desired vs actual speed",
      y_label: "m/s",
      outputs: ["desired_speed_m_s", "speed_m_s"],
    }],
    opt_in: false,
    derives: false,
    learned_model: null,
    fingerprint: null,
  },
  sdre_knee: {
    label: "SDRE knee angle from IMUs (seed 002)",
    outputs: { knee_sdre_deg: "deg", thigh_sdre_deg: "deg" },
    quantities: { knee_sdre_deg: "knee_angle" },
    plots: [],
    opt_in: true,
    derives: false,
    learned_model: null,
    fingerprint: null,
  },
  gp_ekf: {
    label: "GP-EKF (seed 003)",
    outputs: {
      phase: "1",
      phase_rate: "1/s",
      in_stance: "bool",
      heel_strike: "bool",
      toe_off: "bool",
      torque_Nm: "N m",
      standing: "1",
      model_version: "code",
      fault: "code",
      time_phase: "1",
    },
    quantities: { phase: "stance_phase", phase_rate: "stance_phase_rate" },
    plots: [],
    opt_in: true,
    derives: false,
    learned_model: "GP-EKF model",
    fingerprint: null,
  },
});

/**
 * The bounds of one field (`FIELD_LIMITS`); a field has only those its schema states.
 * @typedef {object} FieldLimit
 * @property {number} [min]
 * @property {number} [max]
 * @property {number} [exclusiveMin]
 * @property {number} [exclusiveMax]
 * @property {number} [minLength]
 * @property {number} [maxLength]
 * @property {string} [pattern]
 * @property {number} [minItems]
 * @property {number} [maxItems]
 */

/**
 * Bounds of every bounded field, per class: `min`, `max` (inclusive), `exclusiveMin`, `exclusiveMax`,
 * `minLength`, `maxLength`, `pattern` (a regular expression source), `minItems`, `maxItems`.
 * @type {Readonly<Record<string, Record<string, FieldLimit>>>}
 */
export const FIELD_LIMITS = deepFreeze({
  SubjectCreate: {
    code: { pattern: "^[A-Za-z0-9][A-Za-z0-9_.-]{0,31}$" },
    leg_length_m: { min: 0.5, max: 1.3 },
    mass_kg: { min: 20.0, max: 250.0 },
    notes: { maxLength: 2000 },
  },
  Subject: {
    code: { pattern: "^[A-Za-z0-9][A-Za-z0-9_.-]{0,31}$" },
    leg_length_m: { min: 0.5, max: 1.3 },
    mass_kg: { min: 20.0, max: 250.0 },
    notes: { maxLength: 2000 },
  },
  SessionCreate: { subject_id: { min: 1, max: 9.223372036854776e+18 } },
  ClusterNode: { running: { min: 0 } },
  SessionSettings: {
    torque_gain: { min: 0.0, max: 3.0 },
    max_torque_Nm: { min: 0.0, max: 80.0 },
    measurement_noise_scale: { min: 0.1, max: 10.0 },
    process_noise_scale: { min: 0.1, max: 10.0 },
    intent_gain_boost: { min: 0.0, max: 0.3 },
    model: { pattern: "^[A-Za-z0-9][A-Za-z0-9_.-]{0,31}$" },
    primary: { pattern: "^[a-z][a-z0-9_]{0,31}$" },
    estimators: { maxItems: 16 },
  },
  SettingsChange: {
    torque_gain: { min: 0.0, max: 3.0 },
    max_torque_Nm: { min: 0.0, max: 80.0 },
    measurement_noise_scale: { min: 0.1, max: 10.0 },
    process_noise_scale: { min: 0.1, max: 10.0 },
    intent_gain_boost: { min: 0.0, max: 0.3 },
    primary: { pattern: "^[a-z][a-z0-9_]{0,31}$" },
    actor: { minLength: 1, maxLength: 64 },
    reason: { maxLength: 500 },
  },
  AnnotationCreate: { text: { minLength: 1, maxLength: 500 }, actor: { minLength: 1, maxLength: 64 } },
  RecordingControl: { name: { maxLength: 100 } },
  UploadCreate: {
    filename: {
      minLength: 1,
      maxLength: 200,
      pattern: "^[^/\\\\\\x00-\\x1f\\x7f-\\x9f\\u2028\\u2029\\u200e\\u200f\\u202a-\\u202e\\u2066-\\u2069]+\\.([Mm][Cc][Aa][Pp]|[Cc][Ss][Vv]|[Pp][Aa][Rr][Qq][Uu][Ee][Tt]|[Cc]3[Dd])$",
    },
    size: { min: 1, max: 9.223372036854776e+18 },
    subject_id: { min: 1, max: 9.223372036854776e+18 },
  },
  RerunRequest: { estimators: { maxItems: 16 }, personalization_id: { min: 1, max: 9.223372036854776e+18 } },
  ViewerFocus: { session_id: { min: 1, max: 9.223372036854776e+18 } },
  ViewerShow: { trial_id: { min: 1, max: 9.223372036854776e+18 }, t: { min: -1000000000.0, max: 1000000000.0 } },
  SensorFrame: { seq: { min: 0, max: 9.223372036854776e+18 }, sent_ns: { min: 0, max: 9.223372036854776e+18 } },
  ModelProvenance: {
    n_samples: { min: 1 },
    n_strides: { min: 1 },
    fourier_order: { min: 1 },
    outputs: { minItems: 4, maxItems: 4 },
    torque_fourier_order: { min: 1 },
  },
  CalibrationRequest: {
    trial_id: { min: 1, max: 9.223372036854776e+18 },
    model: { pattern: "^[A-Za-z0-9][A-Za-z0-9_.-]{0,31}$" },
    actor: { minLength: 1, maxLength: 64 },
    note: { maxLength: 500 },
  },
  PersonalizationChange: { actor: { minLength: 1, maxLength: 64 }, reason: { maxLength: 500 } },
  Personalization: { fingerprint: { maxItems: 16 } },
  PersonalizationExport: {
    subject_code: { pattern: "^[A-Za-z0-9][A-Za-z0-9_.-]{0,31}$" },
    model: { pattern: "^[A-Za-z0-9][A-Za-z0-9_.-]{0,31}$" },
    model_sha256: { pattern: "^[0-9a-f]{64}$" },
    fingerprint: { minItems: 1, maxItems: 16 },
    fit_rmse_avg_deg: { min: 0 },
    fit_rmse_personal_deg: { min: 0 },
    strides_used: { min: 0, max: 9.223372036854776e+18 },
    seconds_used: { min: 0 },
    created_utc: { maxLength: 40 },
    note: { maxLength: 500 },
  },
  ImuCalibrationRequest: { duration_s: { min: 2.0, max: 30.0 }, actor: { minLength: 1, maxLength: 64 }, note: { maxLength: 500 } },
  ImuCalibration: {
    duration_s: { min: 0 },
    reason: { maxLength: 2000 },
    sensors: { maxItems: 16 },
    created_utc: { maxLength: 40 },
    created_by: { maxLength: 64 },
    note: { maxLength: 500 },
  },
  ImuCalibrationStatus: { progress: { min: 0.0, max: 1.0 } },
  GPArray: { shape: { maxItems: 4 } },
  GPModelRecord: {
    version: { min: 0, max: 9.223372036854776e+18 },
    steps: { minItems: 2, maxItems: 2 },
    span_s: { minItems: 2, maxItems: 2 },
    reason: { maxLength: 2000 },
    actor: { maxLength: 64 },
  },
  EstimationState: { encoding: { maxLength: 64 }, estimators: { maxItems: 64 }, sha256: { pattern: "^[0-9a-f]{64}$" } },
  GPModelInfo: { steps: { minItems: 2, maxItems: 2 }, span_s: { minItems: 2, maxItems: 2 } },
  GPPendingFit: { steps: { minItems: 2, maxItems: 2 }, span_s: { minItems: 2, maxItems: 2 } },
  GPLearningControl: {
    version: { min: 0, max: 9.223372036854776e+18 },
    actor: { minLength: 1, maxLength: 64 },
    reason: { maxLength: 500 },
  },
  SummaryProgress: { progress: { min: 0.0, max: 1.0 } },
  ExportJob: { progress: { min: 0.0, max: 1.0 } },
  CompareRequest: { runs: { minItems: 2, maxItems: 4 } },
  ReviewAnnotationCreate: {
    t: { min: 0.0, max: 1000000000.0 },
    t_end: { min: 0.0, max: 1000000000.0 },
    text: { minLength: 1, maxLength: 500 },
    actor: { minLength: 1, maxLength: 64 },
  },
  ReviewAnnotation: {
    t: { min: 0.0, max: 1000000000.0 },
    t_end: { min: 0.0, max: 1000000000.0 },
    text: { minLength: 1, maxLength: 500 },
    actor: { minLength: 1, maxLength: 64 },
  },
  SettingsUndo: { actor: { minLength: 1, maxLength: 64 } },
  UserCreate: { name: { pattern: "^[a-z][a-z0-9_.-]{1,31}$" }, password: { minLength: 10, maxLength: 256 } },
  UserChange: { password: { minLength: 10, maxLength: 256 } },
  LoginRequest: { name: { minLength: 1, maxLength: 64 }, password: { minLength: 1, maxLength: 256 } },
  PasswordChange: { current: { minLength: 1, maxLength: 256 }, new: { minLength: 10, maxLength: 256 } },
  AssistanceLimits: {
    torque_gain: { min: 0.0, max: 3.0 },
    max_torque_Nm: { min: 0.0, max: 80.0 },
    intent_gain_boost: { min: 0.0, max: 0.3 },
  },
  SubjectLimits: {
    torque_gain: { min: 0.0, max: 3.0 },
    max_torque_Nm: { min: 0.0, max: 80.0 },
    intent_gain_boost: { min: 0.0, max: 0.3 },
  },
  AuditEntry: {
    seq: { min: 1 },
    prev_hash: { pattern: "^[0-9a-f]{64}$" },
    hash: { pattern: "^[0-9a-f]{64}$" },
    mac: { pattern: "^[0-9a-f]{64}$" },
  },
  AuditQuery: {
    user: { minLength: 1, maxLength: 64 },
    action: { minLength: 1, maxLength: 128 },
    target: { minLength: 1, maxLength: 256 },
    since: { maxLength: 40 },
    until: { maxLength: 40 },
    limit: { min: 1, max: 1000 },
    offset: { min: 0, max: 9.223372036854776e+18 },
  },
  TorqueRaiseRefused: {
    message: { maxLength: 1000 },
    peak_before_Nm: { min: 0.0 },
    peak_after_Nm: { min: 0.0 },
    retry_after_s: { min: 0.0 },
  },
  TorqueCheck: { peak_before_Nm: { min: 0.0 }, peak_after_Nm: { min: 0.0 }, retry_after_s: { min: 0.0 } },
  RegisteredEstimator: { name: { pattern: "^[a-z][a-z0-9_]{0,31}$" } },
  ComparedRunSpec: { name: { minLength: 1, maxLength: 40 }, estimators: { maxItems: 16 } },
  DeviceSource: { rate_hz: { min: 1.0, max: 1000.0 }, channels: { maxItems: 256 } },
  ImuSensorCalibration: {
    segment: { pattern: "^[a-z_]{1,32}$" },
    reason: { maxLength: 500 },
    pitch_offset_deg: { min: -180.0, max: 180.0 },
    gyro_bias_dps: { minItems: 3, maxItems: 3 },
  },
  LslSource: {
    name: { pattern: "^[^'\\\"\\\\]{1,200}$" },
    type: { pattern: "^[^'\\\"\\\\]{1,200}$" },
    source_id: { pattern: "^[^'\\\"\\\\]{1,200}$" },
    resolve_timeout_s: { min: 0.1, max: 30.0 },
    quiet_s: { min: 0.1, max: 60.0 },
  },
  ProtocolStep: {
    speed_m_s: { min: 0.3, max: 2.0 },
    incline_deg: { min: -15.0, max: 15.0 },
    strides: { min: 1, max: 2000 },
  },
  ReplaySource: { trial_id: { min: 1, max: 9.223372036854776e+18 }, speed: { min: 1.0, max: 50.0 } },
  SimulatedSource: {
    protocol: { minItems: 1, maxItems: 200 },
    rate_hz: { min: 20.0, max: 1000.0 },
    cohort_subject: { min: 0, max: 9 },
    seed: { min: 0, max: 9.223372036854776e+18 },
  },
  UploadSource: { filename: { maxLength: 200 }, sha256: { pattern: "^[0-9a-f]{64}$" } },
});

"""Sensor simulation and resampling of clean walks from :mod:`gaitscope.sessions.synth.cohort`.

:func:`simulate_sensors` turns a clean walk into the replay CSV's columns (``schema.REPLAY_*``) with
white sensor noise whose default standard deviations are seed 000's sensor covariance
``diag(1^2, 10^2, 7^2, 20^2, 0.01^2, 0.08^2)`` (deg, deg/s, m). :func:`resample_walk` puts a walk on a
uniform time grid (e.g. 100 Hz, like the hardware of seed 000).

:func:`simulate_sensors` also simulates every channel schema version 2 of the sensor frame adds (the
other leg, joint encoders, one IMU per segment, foot forces and contact, the device's torque and
current, the belt, the last step and the centre of mass; :func:`device_channels`, sources in
``docs/cohort.md``) from its own random stream, so the version 1 channels keep their noise draw for draw.

Both take ONE walk: ``time_s`` must never decrease. Stride boundaries appear twice in a generated walk
(the last sample of a stride and the first of the next are the same instant); both functions keep the
later copy (phase 0 of the new stride) and carry any event flag of the dropped copy over to it.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np
import pandas as pd

from gaitscope.sessions import schema as s
from gaitscope.sessions.synth.imu import ImuSpec, draw_errors, imu_readings

EVENT_COLUMNS = (s.HEEL_STRIKE, s.TOE_OFF, s.HEEL_STRIKE_CONTRA)
#: Columns constant within a stride: taken from the stride a resampled sample falls in.
STRIDE_COLUMNS = (s.STEP, s.PHASE_RATE, s.STRIDE_LENGTH, s.STEP_LENGTH, s.STEP_LENGTH_CONTRA, s.INCLINE, s.SPEED)
#: Ground-truth columns of the simulated replay CSV.
THIGH_FOR_VIEW = "thigh_angle_deg"
GROUND_TRUTH = ("gt_phase", "gt_phase_rate", "gt_stride_length_m", "gt_incline_deg", "gt_speed_m_s")
DUPLICATE_TOL_S = 1e-9
#: Decimals kept of the channels schema version 2 added (:func:`device_channels`).
DECIMALS = 4


@dataclass(frozen=True)
class SensorNoise:
    """Standard deviations of white sensor noise; defaults are seed 000's sensor covariance."""

    foot_angle_deg: float = 1.0
    foot_vel_dps: float = 10.0
    shank_angle_deg: float = 7.0
    shank_vel_dps: float = 20.0
    heel_forward_m: float = 0.01
    heel_up_m: float = 0.08

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not (np.isfinite(value) and value >= 0):
                raise ValueError(f"SensorNoise.{f.name} must be finite and >= 0, got {value}")


def drop_duplicate_instants(walk: pd.DataFrame) -> pd.DataFrame:
    """One row per instant: drop the earlier copy of each repeated time, keeping its event flags."""
    t = walk[s.TIME_S].to_numpy(np.float64)
    dt = np.diff(t)
    if np.any(dt < -DUPLICATE_TOL_S):
        i = int(np.argmax(dt < -DUPLICATE_TOL_S))
        raise ValueError(f"time_s decreases after row {i} ({t[i]} -> {t[i + 1]}): pass one walk at a time")
    first = np.flatnonzero(dt <= DUPLICATE_TOL_S)
    second = first + 1
    if s.STEP in walk.columns and first.size:  # an unstable sort may have put the new stride's copy first
        step = walk[s.STEP].to_numpy()
        swap = step[first] > step[second]
        first[swap], second[swap] = second[swap], first[swap].copy()
    out = walk.copy()
    for col in EVENT_COLUMNS:
        if col in out.columns and first.size:
            v = out[col].to_numpy(np.float64).copy()
            v[second] = np.maximum(v[second], v[first])
            out[col] = v
    return out.drop(index=out.index[first]).reset_index(drop=True)


def simulate_sensors(
    walk: pd.DataFrame, noise: SensorNoise, rng: np.random.Generator, device: DeviceSensors | None = None
) -> pd.DataFrame:
    """Replay-CSV columns from a clean walk, with white noise of ``noise`` added to each signal, and every
    other channel of the sensor frame (:func:`device_channels`, sensors ``device``).

    Angular velocities are the central difference in time of the CLEAN angles (``np.gradient``, second
    order on the uneven grid at stride boundaries) plus gyro noise; heel positions are raw (not
    high-passed). Noise is drawn channel by channel in ``schema.REPLAY_SIGNALS`` order; the other
    channels' from a stream spawned from ``rng`` (``rng.spawn``), which leaves ``rng``'s draws as they were.

    Returns:
        ``time_s``, the six ``REPLAY_SIGNALS``, ``heel_strike`` (0/1 int) and the ground truth
        ``gt_phase`` (0..1), ``gt_phase_rate`` (1/s), ``gt_stride_length_m``, ``gt_incline_deg``,
        ``gt_speed_m_s``, ``thigh_angle_deg``, then the other channels of
        :data:`~gaitscope.sessions.schema.CHANNELS` the walk's columns allow, named as the channels.
    """
    w = drop_duplicate_instants(walk)
    t = w[s.TIME_S].to_numpy(np.float64)
    n = len(t)
    foot = np.degrees(w[s.FOOT_ANGLE].to_numpy(np.float64))
    shank = np.degrees(w[s.SHANK_ANGLE].to_numpy(np.float64))

    def rate(x: np.ndarray) -> np.ndarray:
        return np.gradient(x, t) if n >= 2 else np.zeros_like(x)

    clean = (
        foot,
        rate(foot),
        shank,
        rate(shank),
        w[s.HEEL_FORWARD].to_numpy(np.float64),
        w[s.HEEL_UP].to_numpy(np.float64),
    )
    sd = (
        noise.foot_angle_deg,
        noise.foot_vel_dps,
        noise.shank_angle_deg,
        noise.shank_vel_dps,
        noise.heel_forward_m,
        noise.heel_up_m,
    )
    cols: dict[str, np.ndarray] = {s.REPLAY_TIME: t}
    for name, x, sigma in zip(s.REPLAY_SIGNALS, clean, sd, strict=True):
        cols[name] = x + sigma * rng.standard_normal(n)
    cols[s.REPLAY_HEEL_STRIKE] = (w[s.HEEL_STRIKE].to_numpy(np.float64) > 0.5).astype(np.int64)
    truth = (
        w[s.PHASE_IPSI].to_numpy(np.float64) / 100,
        w[s.PHASE_RATE],
        w[s.STRIDE_LENGTH],
        w[s.INCLINE],
        w[s.SPEED],
    )
    for name, x in zip(GROUND_TRUTH, truth, strict=True):
        cols[name] = np.asarray(x, dtype=np.float64)
    cols[THIGH_FOR_VIEW] = np.degrees(w[s.THIGH_ANGLE].to_numpy(np.float64))  # clean unless device says
    (extra,) = rng.spawn(1)  # schema version 2's channels: their own stream
    cols.update(device_channels(w, noise, device or DeviceSensors(), extra))
    return pd.DataFrame(cols)


@dataclass(frozen=True)
class DeviceSensors:
    """The sensors of schema version 2's channels (defaults: sources in ``docs/cohort.md``).

    The contralateral foot and shank angles and angular velocities take :class:`SensorNoise`'s figures
    (the same sensors on the other leg). Thigh angles stay clean by default, as the version 1 thigh
    channel (which drove the leg view only) was; give ``thigh_angle_deg`` and ``thigh_vel_dps`` to add
    noise to both legs' thigh channels.

    Attributes:
        imu: every segment's IMU (an MPU-9250 by default).
        thigh_angle_deg, thigh_vel_dps: white-noise sd of both legs' thigh channels (deg, deg/s).
        encoder_counts: joint encoder counts per revolution (14 bits, the ExoBoot's ``ank_ang`` as
            UM-LoCoLab/NeuroLocoMiddleware's ``EB51Man.py`` reads it); encoder angles are quantised to it.
        force_N: white-noise sd of the vertical foot forces (N, choice); readings are floored at 0.
        contact_bw: a foot is in contact while its force exceeds this fraction of body weight (seed 001's
            touchdown rule: above 5 % of the maximum).
        torque_ratio: commanded torque per biological ankle moment (seed 000: 1/5, plantarflexion only).
        max_torque_Nm: the command's bound (the sessions' default).
        torque_constant_Nm_A: the motor's q-axis torque constant (Dephy ActPack, ``NM_PER_AMP`` in
            UM-LoCoLab/NeuroLocoMiddleware's ``ActPackMan.py``).
        transmission_ratio: motor turns per joint turn (choice: the ExoBoot's belt ratio varies with the
            ankle angle and is calibrated per device; one constant stands in for it).
        current_A: white-noise sd of the motor current (A, choice).
    """

    imu: ImuSpec = field(default_factory=ImuSpec)
    thigh_angle_deg: float = 0.0
    thigh_vel_dps: float = 0.0
    encoder_counts: int = 2**14
    force_N: float = 5.0
    contact_bw: float = 0.05
    torque_ratio: float = 0.2
    max_torque_Nm: float = 30.0
    torque_constant_Nm_A: float = 0.1133
    transmission_ratio: float = 16.0
    current_A: float = 0.05


def device_channels(
    w: pd.DataFrame, noise: SensorNoise, device: DeviceSensors, rng: np.random.Generator
) -> dict[str, np.ndarray]:
    """The channels schema version 2 adds, by channel name, from a walk with its duplicate instants
    dropped; each group only when the walk has its clean columns (a generated walk has them all).

    Noise comes from ``rng`` alone, drawn group by group in the order of this function. Values (but the
    version 1 thigh angle, kept as it was) are rounded to :data:`DECIMALS` decimals of their unit, far
    below every channel's noise or resolution (as a device sends them; it keeps recorded frames short).
    """
    t = w[s.TIME_S].to_numpy(np.float64)
    n = len(t)
    rate_hz = 1.0 / float(np.median(np.diff(t))) if n > 1 else 100.0

    def col(name: str) -> np.ndarray:
        return w[name].to_numpy(np.float64)

    def deg(name: str) -> np.ndarray:
        return np.degrees(col(name))

    def rate(x: np.ndarray) -> np.ndarray:
        return np.gradient(x, t) if n >= 2 else np.zeros_like(x)

    def noisy(x: np.ndarray, sd: float) -> np.ndarray:
        return x + sd * rng.standard_normal(n)

    out: dict[str, np.ndarray] = {}
    # segment angles and angular velocities (processed, as the version 1 channels)
    thigh = deg(s.THIGH_ANGLE)
    out[THIGH_FOR_VIEW] = noisy(thigh, device.thigh_angle_deg)
    out["thigh_vel_dps"] = noisy(rate(thigh), device.thigh_vel_dps)
    if s.THIGH_ANGLE_CONTRA in w:
        for seg, column, angle_sd, vel_sd in (
            ("foot", s.FOOT_ANGLE_CONTRA, noise.foot_angle_deg, noise.foot_vel_dps),
            ("shank", s.SHANK_ANGLE_CONTRA, noise.shank_angle_deg, noise.shank_vel_dps),
            ("thigh", s.THIGH_ANGLE_CONTRA, device.thigh_angle_deg, device.thigh_vel_dps),
        ):
            x = deg(column)
            out[f"{seg}_angle_contra_deg"] = noisy(x, angle_sd)
            out[f"{seg}_vel_contra_dps"] = noisy(rate(x), vel_sd)
    # joint encoders
    step = 360.0 / device.encoder_counts
    joints = {"hip_angle_deg": s.HIP_ANGLE, "knee_angle_deg": s.KNEE_ANGLE, "ankle_angle_deg": s.ANKLE_ANGLE}
    if s.KNEE_ANGLE_CONTRA in w:
        joints |= {
            "hip_angle_contra_deg": s.HIP_ANGLE_CONTRA,
            "knee_angle_contra_deg": s.KNEE_ANGLE_CONTRA,
            "ankle_angle_contra_deg": s.ANKLE_ANGLE_CONTRA,
        }
    for name, column in joints.items():
        out[name] = np.round(deg(column) / step) * step
    # IMUs
    if all(a in w for pair in s.IMU_POINT_ACCELERATION.values() for a in pair):
        lateral = -rate(col(s.COM_VELOCITY[1]))  # the cohort's lateral is + left; the sensors' z is right
        for seg in s.IMU_SEGMENTS:
            angle = -deg(s.PELVIS_ANGLE) if seg == "pelvis" else deg(_SEGMENT_ANGLE[seg])
            fwd, up = (col(c) for c in s.IMU_POINT_ACCELERATION[seg])
            errors = draw_errors(device.imu, rng)
            gyro, accel = imu_readings(
                angle, rate(angle), np.stack([fwd, up, lateral], axis=1), rate_hz, device.imu, errors, rng
            )
            for i, axis in enumerate("xyz"):
                out[f"imu_{seg}_gyro_{axis}_dps"] = gyro[:, i]
                out[f"imu_{seg}_accel_{axis}_m_s2"] = accel[:, i]
    # feet
    if s.VERTICAL_GRF in w:
        weight = _body_mass(w) * 9.81
        for side, column in (("", s.VERTICAL_GRF), ("_contra", s.VERTICAL_GRF_CONTRA)):
            force = np.maximum(noisy(col(column), device.force_N), 0.0)
            out[f"foot_force{side}_N"] = force
            out[f"foot_contact{side}"] = force > device.contact_bw * weight
    # device: the biomimetic command at the true state (seed 000), and the motor current it takes
    torque = np.clip(-device.torque_ratio * col(s.ANKLE_MOMENT), 0.0, device.max_torque_Nm)
    out["commanded_torque_Nm"] = torque
    out["motor_current_A"] = noisy(torque / (device.torque_constant_Nm_A * device.transmission_ratio), device.current_A)
    # treadmill, last step, centre of mass (clean: the treadmill's set speed, a lab's measurement)
    out["belt_speed_m_s"] = col(s.SPEED)
    if s.STEP_LENGTH_CONTRA in w:
        out["step_length_m"] = np.where(_contra_stance(w), col(s.STEP_LENGTH_CONTRA), col(s.STEP_LENGTH))
    if s.COM_STANCE_POSITION[0] in w:
        v, r = col(s.SPEED), np.radians(col(s.INCLINE))
        out["com_forward_m"] = col(s.COM_STANCE_POSITION[0])
        out["com_lateral_m"] = -col(s.COM_STANCE_POSITION[1])
        out["com_up_m"] = col(s.COM_STANCE_POSITION[2])
        out["com_forward_vel_m_s"] = col(s.COM_VELOCITY[0]) - v * (1.0 - np.cos(r))  # the foot moves with the belt
        out["com_lateral_vel_m_s"] = -col(s.COM_VELOCITY[1])
        out["com_up_vel_m_s"] = col(s.COM_VELOCITY[2]) + v * np.sin(r)
    return {k: v if v.dtype == bool or k == THIGH_FOR_VIEW else np.round(v, DECIMALS) for k, v in out.items()}


#: LocoHub column of each leg segment's sagittal angle.
_SEGMENT_ANGLE = {
    "thigh": s.THIGH_ANGLE,
    "shank": s.SHANK_ANGLE,
    "foot": s.FOOT_ANGLE,
    "thigh_contra": s.THIGH_ANGLE_CONTRA,
    "shank_contra": s.SHANK_ANGLE_CONTRA,
    "foot_contra": s.FOOT_ANGLE_CONTRA,
}


def _body_mass(w: pd.DataFrame) -> float:
    """The walker's mass (kg) from ``subject_metadata`` (``mass_kg:..``)."""
    text = str(w[s.SUBJECT_METADATA].iloc[0])
    return float(dict(item.split(":", 1) for item in text.split(","))["mass_kg"])


def _contra_stance(w: pd.DataFrame) -> np.ndarray:
    """True where the contralateral foot touched down last (its heel strike is the latest event)."""
    idx = np.arange(len(w))
    last_ipsi = np.maximum.accumulate(np.where(w[s.HEEL_STRIKE].to_numpy() > 0.5, idx, -1))
    last_contra = np.maximum.accumulate(np.where(w[s.HEEL_STRIKE_CONTRA].to_numpy() > 0.5, idx, -1))
    return last_contra > last_ipsi


def resample_walk(walk: pd.DataFrame, rate_hz: float) -> pd.DataFrame:
    """The same walk on a uniform grid ``t0 + k / rate_hz`` up to its last instant.

    Numeric signals are interpolated linearly in time; phase is interpolated unwrapped
    (``step + phase / 100``) and wrapped back within the stride; per-stride columns (``STRIDE_COLUMNS``)
    and text columns come from the stride each grid sample falls in; each event is set on the grid
    sample nearest in time. Column order and dtypes are kept.
    """
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise ValueError(f"rate_hz must be positive, got {rate_hz}")
    w = drop_duplicate_instants(walk)
    t = w[s.TIME_S].to_numpy(np.float64)
    if len(t) < 2:
        raise ValueError("a walk needs at least two distinct instants to resample")
    n_new = int(np.floor((t[-1] - t[0]) * rate_hz + 1e-9)) + 1
    t_new = t[0] + np.arange(n_new) / rate_hz
    src = np.clip(np.searchsorted(t, t_new, side="right") - 1, 0, len(t) - 1)  # row at or before
    out: dict[str, np.ndarray] = {}
    for col in w.columns:
        x = w[col]
        if col == s.TIME_S:
            out[col] = t_new
        elif col in EVENT_COLUMNS:
            e = np.zeros(n_new)
            t_event = t[x.to_numpy(np.float64) > 0.5]
            hit = np.clip(np.rint((t_event - t[0]) * rate_hz).astype(int), 0, n_new - 1)
            e[hit] = 1.0
            out[col] = e
        elif col == s.PHASE_IPSI and s.STEP in w.columns:
            step = w[s.STEP].to_numpy(np.float64)
            u = np.interp(t_new, t, step + x.to_numpy(np.float64) / 100)
            out[col] = np.clip(100 * (u - step[src]), 0.0, 100.0)
        elif col in STRIDE_COLUMNS or not pd.api.types.is_numeric_dtype(x.dtype):
            out[col] = x.to_numpy()[src]
        else:
            out[col] = np.interp(t_new, t, x.to_numpy(np.float64))
    return pd.DataFrame(out).astype(w.dtypes.to_dict())

"""Sensor simulation and resampling of clean walks from :mod:`sessions.synth.cohort`.

:func:`simulate_sensors` turns a clean walk into the replay CSV's columns (``schema.REPLAY_*``) with
white sensor noise whose default standard deviations are seed 000's sensor covariance
``diag(1^2, 10^2, 7^2, 20^2, 0.01^2, 0.08^2)`` (deg, deg/s, m). :func:`resample_walk` puts a walk on a
uniform time grid (e.g. 100 Hz, like the hardware of seed 000).

Both take ONE walk: ``time_s`` must never decrease. Stride boundaries appear twice in a generated walk
(the last sample of a stride and the first of the next are the same instant); both functions keep the
later copy (phase 0 of the new stride) and carry any event flag of the dropped copy over to it.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
import pandas as pd

from sessions import schema as s

EVENT_COLUMNS = (s.HEEL_STRIKE, s.TOE_OFF, s.HEEL_STRIKE_CONTRA)
#: Columns constant within a stride: taken from the stride a resampled sample falls in.
STRIDE_COLUMNS = (s.STEP, s.PHASE_RATE, s.STRIDE_LENGTH, s.STEP_LENGTH, s.INCLINE, s.SPEED)
#: Ground-truth columns of the simulated replay CSV.
THIGH_FOR_VIEW = "thigh_angle_deg"
GROUND_TRUTH = ("gt_phase", "gt_phase_rate", "gt_stride_length_m", "gt_incline_deg", "gt_speed_m_s")
DUPLICATE_TOL_S = 1e-9


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


def simulate_sensors(walk: pd.DataFrame, noise: SensorNoise, rng: np.random.Generator) -> pd.DataFrame:
    """Replay-CSV columns from a clean walk, with white noise of ``noise`` added to each signal.

    Angular velocities are the central difference in time of the CLEAN angles (``np.gradient``, second
    order on the uneven grid at stride boundaries) plus gyro noise; heel positions are raw (not
    high-passed). Noise is drawn channel by channel in ``schema.REPLAY_SIGNALS`` order.

    Returns:
        ``time_s``, the six ``REPLAY_SIGNALS``, ``heel_strike`` (0/1 int) and the ground truth
        ``gt_phase`` (0..1), ``gt_phase_rate`` (1/s), ``gt_stride_length_m``, ``gt_incline_deg``,
        ``gt_speed_m_s``.
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
    cols[THIGH_FOR_VIEW] = np.degrees(w[s.THIGH_ANGLE].to_numpy(np.float64))  # clean: drives the leg view only
    return pd.DataFrame(cols)


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

"""Walks with what real walking contains: starts, stops, standing, turns, sensor offsets, drift, dropouts.

The virtual cohort walks straight at constant speed with white sensor noise. Real recordings (foot and
shank IMUs, walks with turns and stops) also have, and this module adds on top of the cohort
(``docs/cohort.md``, "Real walking"; every number is a parameter of :class:`RealWalkSpec`):

- **bouts** separated by **standing** (3-6 s): each bout starts from standing and ends in it. Someone
  standing has both feet in stance, so the instrumented leg starts at ``rest_phase`` (0.3, mid-stance)
  of its first stride and ends at it after its last heel strike (gait termination: the last step lands
  and the body comes to rest over it; initiation and termination as in Miff et al. 2008, Gait & Posture
  27:316-322); the signals blend from
  the standing posture over the first ``blend_strides`` (0.25 stride) and back over the last (the
  posture: the first bout's mean at mid-stance, phase 0.25-0.35, velocities 0). ``rest_phase=0`` with
  ``blend_strides=0.5`` gives bouts that start and end at a heel strike, the truth advancing through
  the blend while the leg is still (this module's labelling before 2026-11-24; the robust study
  reports both);
- **starts and stops**: steady speed is reached with the third step (Hollander et al., sloped gait
  initiation: at least 90-95 % of steady speed by the 3rd step on the level), so the first stride
  (steps 1-2) is at 60 % of the bout's speed and the second at 90 %; stopping takes the last two
  strides at 80 % and 50 % (choice, mirrored);
- **turns**: one 90 deg turn per bout over two strides, slower (70 % speed) and with shorter strides
  (85 % of the straight stride at that speed): turning walkers lower cadence and step length (Madrid et
  al. 2024, 90-360 deg turns); turns are 20-50 % of daily steps (Glaister et al. 2007). A sensor's
  sagittal axis is misaligned with the limb's by a few degrees (``cross_axis_sd_deg``), so the turn's
  yaw rate leaks into its pitch gyro: the foot angle (integrated gyro, re-zeroed at each foot-flat)
  gains that leak's integral since the last foot-flat, the shank angle (a complementary filter,
  ``complementary_tau_s``) its low-passed integral;
- **mounting offsets** per sensor and walk (foot sd 3 deg, shank sd 5 deg; a shank IMU on a real walk was
  20 deg off its standing posture) and **gyro bias** (sd 0.5 deg/s), integrated the same way;
- **dropouts**: each sensor (foot IMU, shank IMU, heel positions) loses its channels (NaN) at a rate of
  ``dropouts_per_min`` for 0.05-0.5 s each.

Ground truth per sample: ``gt_phase`` (NaN while standing), ``gt_phase_rate`` (0 while standing) and
``condition``: ``steady``, ``start``, ``stop``, ``turn`` (the turn's strides and the one after) or
``standing``. Deterministic from the spec's seed and the subject.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from gaitscope.sessions import schema as s
from gaitscope.sessions.synth.body import smooth_step
from gaitscope.sessions.synth.cohort import (
    CohortSpec,
    SensorNoise,
    SubjectParams,
    generate_walk,
    make_subjects,
    resample_walk,
    simulate_sensors,
)

__all__ = ["CONDITIONS", "SENSORS", "RealWalkSpec", "real_walk", "real_walks"]

#: Labels of the ``condition`` column.
CONDITIONS = ("steady", "start", "stop", "turn", "standing")
#: Each sensor's channels (a dropout takes them all).
SENSORS = {
    "foot": ("foot_angle_deg", "foot_vel_dps"),
    "shank": ("shank_angle_deg", "shank_vel_dps"),
    "heel": ("heel_forward_m", "heel_up_m"),
}


@dataclass(frozen=True)
class RealWalkSpec:
    """What a real walk adds to the cohort (defaults and sources: the module docstring)."""

    bouts: int = 3
    steady_strides: tuple[int, int] = (6, 10)
    speed_range_m_s: tuple[float, float] = (0.9, 1.3)
    start_fractions: tuple[float, ...] = (0.6, 0.9)
    stop_fractions: tuple[float, ...] = (0.8, 0.5)
    rest_phase: float = 0.3
    blend_strides: float = 0.25
    turn_strides: int = 2
    turn_speed_fraction: float = 0.7
    turn_stride_fraction: float = 0.85
    turn_deg: float = 90.0
    standing_s: tuple[float, float] = (3.0, 6.0)
    mount_sd_deg: tuple[float, float] = (3.0, 5.0)  # foot, shank
    gyro_bias_sd_dps: float = 0.5
    cross_axis_sd_deg: float = 5.0
    complementary_tau_s: float = 1.0
    dropouts_per_min: float = 2.0
    dropout_s: tuple[float, float] = (0.05, 0.5)
    rate_hz: float = 100.0
    seed: int = 20261123


def _bout_schedule(spec: RealWalkSpec, rng: np.random.Generator) -> tuple[list[float], np.ndarray, list[str]]:
    """Per-stride speeds, stride-length scales and labels of one bout."""
    v = float(rng.uniform(*spec.speed_range_m_s))
    n_steady = int(rng.integers(spec.steady_strides[0], spec.steady_strides[1] + 1))
    turn_at = int(rng.integers(2, max(3, n_steady - 2)))
    strides = [(v * f, 1.0, "start") for f in spec.start_fractions]
    for k in range(n_steady):
        if turn_at <= k < turn_at + spec.turn_strides:
            strides.append((v * spec.turn_speed_fraction, spec.turn_stride_fraction, "turn"))
        else:  # the stride after the turn still counts to it (the walker straightens out)
            strides.append((v, 1.0, "turn" if k == turn_at + spec.turn_strides else "steady"))
    strides += [(v * f, 1.0, "stop") for f in spec.stop_fractions]
    if spec.rest_phase > 0:  # the last heel strike's stance, up to the rest phase
        strides.append((v * spec.stop_fractions[-1], 1.0, "stop"))
    return [x[0] for x in strides], np.array([x[1] for x in strides]), [x[2] for x in strides]


def _bout(subject: SubjectParams, spec: RealWalkSpec, rng: np.random.Generator) -> pd.DataFrame:
    speeds, scales, labels = _bout_schedule(spec, rng)
    walk = generate_walk(subject, [(sp, 0.0, 1) for sp in speeds], rng, stride_scale=scales)
    f = simulate_sensors(resample_walk(walk, spec.rate_hz), SensorNoise(), rng)
    f = f[[s.REPLAY_TIME, *s.REPLAY_SIGNALS, s.REPLAY_HEEL_STRIKE, "gt_phase", "gt_phase_rate"]].copy()
    starts = walk.loc[walk[s.PHASE_IPSI] == 0.0, s.TIME_S].to_numpy(np.float64)
    stride = np.clip(np.searchsorted(starts, f[s.REPLAY_TIME].to_numpy(), side="right") - 1, 0, len(labels) - 1)
    f["condition"] = np.array(labels, dtype=object)[stride]
    f["turn_weight"] = np.where(f["condition"].to_numpy() == "turn", 1.0, 0.0)
    if spec.rest_phase > 0:  # from rest at the rest phase of the first stride to it in the last
        phase = f["gt_phase"].to_numpy()
        first, last = stride == 0, stride == len(labels) - 1
        f = f[~((first & (phase < spec.rest_phase)) | (last & (phase > spec.rest_phase)))].reset_index(drop=True)
    durations = np.diff(starts)
    f.attrs["blend_s"] = spec.blend_strides * (float(durations[0]) if len(durations) else 1.0)
    return f


def _posture(f: pd.DataFrame) -> dict[str, float]:
    """The standing posture: the bout's mean at mid-stance (phase 0.25-0.35: foot flat, shank near upright),
    velocities 0."""
    flat = f["gt_phase"].between(0.25, 0.35).to_numpy()
    posture = {c: float(f.loc[flat, c].mean()) for c in s.REPLAY_SIGNALS}
    return posture | {"foot_vel_dps": 0.0, "shank_vel_dps": 0.0}


def _blend(f: pd.DataFrame, posture: dict[str, float]) -> None:
    """From and to the standing posture over ``blend_strides`` at each end, in place."""
    t = f[s.REPLAY_TIME].to_numpy(np.float64)
    blend = float(f.attrs["blend_s"])
    w = smooth_step((t - t[0]) / blend) * smooth_step((t[-1] - t) / blend)
    for c in s.REPLAY_SIGNALS:
        f[c] = posture[c] + w * (f[c].to_numpy() - posture[c])


def _standing(
    posture: dict[str, float], t0: float, duration: float, spec: RealWalkSpec, rng: np.random.Generator
) -> pd.DataFrame:
    n = max(1, round(duration * spec.rate_hz))
    t = t0 + np.arange(1, n + 1) / spec.rate_hz
    noise = SensorNoise()
    sd = dict(zip(s.REPLAY_SIGNALS, dataclasses.astuple(noise), strict=True))
    cols: dict[str, object] = {s.REPLAY_TIME: t}
    for c in s.REPLAY_SIGNALS:
        cols[c] = posture[c] + sd[c] * 0.2 * rng.standard_normal(n)  # standing still: a fifth of walking's noise
    cols |= {s.REPLAY_HEEL_STRIKE: np.zeros(n, np.int64), "gt_phase": np.full(n, np.nan), "gt_phase_rate": np.zeros(n)}
    cols |= {"condition": np.full(n, "standing", dtype=object), "turn_weight": np.zeros(n)}
    return pd.DataFrame(cols)


def _sensor_errors(f: pd.DataFrame, spec: RealWalkSpec, rng: np.random.Generator) -> None:
    """Mounting offsets, gyro bias and the turns' yaw leak (integrated as each sensor's angle is), and
    dropouts, in place."""
    t = f[s.REPLAY_TIME].to_numpy(np.float64)
    dt = np.r_[0.0, np.diff(t)]
    # yaw rate: each turn's 90 deg spread over its samples (turn_weight marks them)
    tw = f["turn_weight"].to_numpy()
    turn_time = float(np.sum(tw * dt))
    n_turns = max(1, spec.bouts)
    yaw = tw * (spec.turn_deg * n_turns / turn_time if turn_time > 0 else 0.0)
    phase = f["gt_phase"].to_numpy()
    foot_flat = np.r_[False, (phase[1:] >= 0.2) & (phase[:-1] < 0.2)] | (f["condition"].to_numpy() == "standing")
    for seg, mount_sd in zip(("foot", "shank"), spec.mount_sd_deg, strict=True):
        angle, vel = SENSORS[seg]
        leak = math.sin(math.radians(rng.normal(0.0, spec.cross_axis_sd_deg))) * yaw
        bias = rng.normal(0.0, spec.gyro_bias_sd_dps)
        rate_error = leak + bias
        err = np.empty(len(t))
        acc = 0.0
        for k in range(len(t)):
            if seg == "foot":
                acc = 0.0 if foot_flat[k] else acc + rate_error[k] * dt[k]  # re-zeroed at foot-flat
            else:
                acc += (rate_error[k] - acc / spec.complementary_tau_s) * dt[k]  # complementary filter
            err[k] = acc
        f[angle] = f[angle].to_numpy() + rng.normal(0.0, mount_sd) + err
        f[vel] = f[vel].to_numpy() + rate_error
    duration_min = (t[-1] - t[0]) / 60.0
    for channels in SENSORS.values():
        for _ in range(rng.poisson(spec.dropouts_per_min * duration_min)):
            a = float(rng.uniform(t[0], t[-1]))
            gone = (t >= a) & (t < a + rng.uniform(*spec.dropout_s))
            for c in channels:
                f.loc[gone, c] = np.nan


def real_walk(subject: SubjectParams, spec: RealWalkSpec | None = None, index: int = 0) -> pd.DataFrame:
    """One subject's walk: standing, then ``bouts`` x (bout, standing), at ``rate_hz``.

    Columns: ``time_s``, the six replay signals, ``heel_strike`` (true), ``gt_phase``, ``gt_phase_rate``,
    ``condition`` (:data:`CONDITIONS`).
    """
    spec = spec or RealWalkSpec()
    rng = np.random.default_rng(np.random.SeedSequence(spec.seed, spawn_key=(int(subject.code[2:]), index)))
    parts: list[pd.DataFrame] = []
    t_end = 0.0
    bouts = [_bout(subject, spec, rng) for _ in range(spec.bouts)]
    posture = _posture(bouts[0])  # one standing posture for the whole walk
    for b in bouts:
        _blend(b, posture)
        stand = _standing(posture, t_end, float(rng.uniform(*spec.standing_s)), spec, rng)
        parts.append(stand)
        t0 = float(stand[s.REPLAY_TIME].iloc[-1]) + 1.0 / spec.rate_hz
        b = b.copy()
        b[s.REPLAY_TIME] = b[s.REPLAY_TIME] - b[s.REPLAY_TIME].iloc[0] + t0
        parts.append(b)
        t_end = float(b[s.REPLAY_TIME].iloc[-1])
    parts.append(_standing(posture, t_end, float(rng.uniform(*spec.standing_s)), spec, rng))
    f = pd.concat(parts, ignore_index=True)
    _sensor_errors(f, spec, rng)
    return f.drop(columns=["turn_weight"])


def real_walks(
    spec: RealWalkSpec | None = None, cohort: CohortSpec | None = None
) -> list[tuple[SubjectParams, pd.DataFrame]]:
    """Every cohort subject's real walk."""
    return [(subj, real_walk(subj, spec)) for subj in make_subjects(cohort or CohortSpec())]

"""Walks at a speed that never settles, ending in a sudden stop: the cohort's data for seed 003's GP-EKF.

Protocol (seed 003, ``../shared/reference/estimators.md`` section 3): the treadmill's speed varies as a
sinusoid between 0.4 and 1.2 m/s with a 20 s period, and the walk ends in a sudden stop. Here:

- **speed** at each stride's start is ``mid + amp * sin(2 pi t / period)`` (0.8 +- 0.4 m/s); each stride
  is its own block of :func:`gaitscope.sessions.synth.cohort.generate_walk`, so its curves, stride length and
  cadence are the subject's at that speed and morph from the previous stride's (nothing jumps). The
  stride start times depend on the speeds and the speeds on the times: a fixed point, found in a few
  passes;
- **sudden stop** after ``walk_s``, when the instrumented leg next reaches gait phase ``stop_phase``
  (0.25, early mid-stance: seed 003's filter estimates stance, so its stop is one in stance; ``None``
  stops at ``walk_s`` wherever the leg is, swing included): the gait phase decelerates uniformly to
  rest over ``stop_s`` (0.3 s, **choice**: the walker brakes within one step; a treadmill's emergency
  stop takes a similar time), every clean signal sampled at the decelerating phase, then stands still
  for ``standing_s`` in that posture;
- sensors as a device sends them (:func:`gaitscope.sessions.synth.sensors.simulate_sensors`, joint encoders
  included) at ``rate_hz`` (200 Hz, the paper's).

Ground truth per sample: ``gt_stance_phase`` (0 at heel strike, 1 at toe-off: the gait phase divided by
the stride's toe-off phase, which is ``t / T_stance`` at constant cadence; NaN in swing),
``gt_stance_rate`` (1/s, 0 standing), ``condition`` (``walking``, ``stopping``, ``standing``) and
``gt_speed_m_s``. Deterministic from the protocol's seed and the subject.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from gaitscope.sessions import schema as s
from gaitscope.sessions.synth.cohort import (
    CohortSpec,
    SensorNoise,
    SubjectParams,
    generate_walk,
    make_subjects,
    resample_walk,
    simulate_sensors,
)

__all__ = ["SpeedProtocol", "speed_at", "speed_walk", "speed_walks"]

#: The clean columns a stop interpolates over phase; the rest are held (text, per-stride values).
_EVENTS = (s.HEEL_STRIKE, s.TOE_OFF, s.HEEL_STRIKE_CONTRA)


@dataclass(frozen=True)
class SpeedProtocol:
    """Seed 003's protocol on the cohort (see the module docstring; every number is a parameter)."""

    speed_range_m_s: tuple[float, float] = (0.4, 1.2)
    period_s: float = 20.0
    walk_s: float = 60.0
    stop_s: float = 0.3
    stop_phase: float | None = 0.25
    standing_s: float = 5.0
    rate_hz: float = 200.0
    seed: int = 20261124

    def __post_init__(self) -> None:
        lo, hi = self.speed_range_m_s
        if not 0 < lo <= hi or self.period_s <= 0 or self.walk_s <= 0 or self.stop_s <= 0 or self.rate_hz <= 0:
            raise ValueError(f"speeds 0 < lo <= hi, period, walk, stop and rate > 0: {self}")


def speed_at(t: np.ndarray | float, protocol: SpeedProtocol) -> np.ndarray:
    """The treadmill speed (m/s) at time ``t`` (s)."""
    lo, hi = protocol.speed_range_m_s
    return np.asarray(0.5 * (lo + hi) + 0.5 * (hi - lo) * np.sin(2 * math.pi * np.asarray(t) / protocol.period_s))


def _strides(subject: SubjectParams, protocol: SpeedProtocol, rng_seed: np.random.SeedSequence) -> pd.DataFrame:
    """The walking part: one stride per block, each at the speed at its own start (a fixed point)."""
    n = max(2, math.ceil(protocol.walk_s / 0.8) + 2)  # more strides than the walk needs at any speed
    speeds = np.full(n, float(speed_at(0.0, protocol)))
    walk = pd.DataFrame()
    for _ in range(6):
        walk = generate_walk(subject, [(float(v), 0.0, 1) for v in speeds], np.random.default_rng(rng_seed))
        starts = walk.loc[walk[s.PHASE_IPSI] == 0.0].groupby(s.STEP)[s.TIME_S].first().to_numpy(np.float64)
        new = speed_at(starts[:n], protocol)
        if np.allclose(new, speeds[: len(new)], atol=1e-4):
            break
        speeds[: len(new)] = new
    return walk


def _stop(walk: pd.DataFrame, protocol: SpeedProtocol) -> pd.DataFrame:
    """The walk up to ``walk_s``, then the phase decelerating to rest over ``stop_s``, then standing."""
    t = walk[s.TIME_S].to_numpy(np.float64)
    k0 = int(np.searchsorted(t, protocol.walk_s))
    if protocol.stop_phase is not None:  # on to the sample where the leg reaches the stop phase
        p = walk[s.PHASE_IPSI].to_numpy(np.float64) / 100.0
        at = np.flatnonzero((p[k0 + 1 :] >= protocol.stop_phase) & (p[k0:-1] < protocol.stop_phase))
        k0 = k0 + 1 + int(at[0]) if len(at) else k0
    stride = int(walk[s.STEP].iloc[k0])
    one = walk[walk[s.STEP] == stride]
    phase = one[s.PHASE_IPSI].to_numpy(np.float64)
    rate = 100.0 * float(one[s.PHASE_RATE].iloc[0])  # percent per second
    t0, p0 = float(t[k0]), float(walk[s.PHASE_IPSI].iloc[k0])
    dt = 1.0 / protocol.rate_hz
    tau = np.arange(1, math.ceil((protocol.stop_s + protocol.standing_s) / dt) + 1) * dt
    moving = np.minimum(tau, protocol.stop_s)
    warped = np.minimum(p0 + rate * (moving - moving**2 / (2 * protocol.stop_s)), phase[-1])
    numeric = [c for c in one.columns if pd.api.types.is_numeric_dtype(one[c]) and c not in (s.TIME_S, s.STEP)]
    rows = pd.DataFrame({c: np.interp(warped, phase, one[c].to_numpy(np.float64)) for c in numeric})
    for c in one.columns:
        if c not in rows:
            rows[c] = one[c].iloc[0]
    rows[s.TIME_S] = t0 + tau
    rows[s.PHASE_IPSI] = warped
    rows[s.PHASE_RATE] = one[s.PHASE_RATE].iloc[0] * np.maximum(0.0, 1.0 - tau / protocol.stop_s)
    for c in _EVENTS:
        if c in rows:
            rows[c] = 0.0
    out = pd.concat([walk.iloc[: k0 + 1], rows[walk.columns]], ignore_index=True)
    out.attrs["stop_t"] = t0
    return out


def _toe_off_phase(walk: pd.DataFrame) -> dict[int, float]:
    """Each stride's toe-off phase (fraction of the stride)."""
    to = walk[walk[s.TOE_OFF] > 0]
    return {int(k): float(p) / 100.0 for k, p in zip(to[s.STEP], to[s.PHASE_IPSI], strict=True)}


def speed_walk(subject: SubjectParams, protocol: SpeedProtocol | None = None, index: int = 0) -> pd.DataFrame:
    """One subject's walk: the sinusoidal speed for ``walk_s``, a sudden stop, standing (module docstring).

    Columns: the sensor frame's channels as :func:`~gaitscope.sessions.synth.sensors.simulate_sensors` makes them
    (joint encoders ``hip_angle_deg``, ``knee_angle_deg``, ``ankle_angle_deg`` among them),
    ``heel_strike``, ``toe_off``, ``gt_stance_phase``, ``gt_stance_rate``, ``gt_speed_m_s``, ``condition``.
    """
    protocol = protocol or SpeedProtocol()
    seq = np.random.SeedSequence(protocol.seed, spawn_key=(int(subject.code[2:]), index))
    walk_seq, sensor_seq = seq.spawn(2)
    walk = _strides(subject, protocol, walk_seq)
    to_phase = _toe_off_phase(walk)
    walk = _stop(walk, protocol)
    stop_t = float(walk.attrs["stop_t"])
    clean = resample_walk(walk, protocol.rate_hz)
    f = simulate_sensors(clean, SensorNoise(), np.random.default_rng(sensor_seq))
    f[s.REPLAY_TIME] = clean[s.TIME_S].to_numpy(np.float64)
    step = clean[s.STEP].to_numpy(np.int64)
    gait = clean[s.PHASE_IPSI].to_numpy(np.float64) / 100.0
    rate = clean[s.PHASE_RATE].to_numpy(np.float64)
    toe = np.array([to_phase.get(int(k), np.nan) for k in step])
    if np.isnan(toe).any():  # the stopped stride never reached its toe-off: the last one seen
        toe = np.where(np.isnan(toe), np.nanmedian(list(to_phase.values())), toe)
    stance = gait <= toe
    t = f[s.REPLAY_TIME].to_numpy(np.float64)
    f["toe_off"] = (clean[s.TOE_OFF].to_numpy() > 0).astype(np.int64)
    f["gt_stance_phase"] = np.where(stance, gait / toe, np.nan)
    f["gt_stance_rate"] = np.where(stance, rate / toe, np.nan)
    f["condition"] = np.where(t <= stop_t, "walking", np.where(t <= stop_t + protocol.stop_s, "stopping", "standing"))
    f["gt_speed_m_s"] = np.where(t <= stop_t, speed_at(t, protocol), 0.0)
    return f


def speed_walks(
    protocol: SpeedProtocol | None = None, cohort: CohortSpec | None = None
) -> list[tuple[SubjectParams, pd.DataFrame]]:
    """Every cohort subject's walk."""
    return [(subj, speed_walk(subj, protocol)) for subj in make_subjects(cohort or CohortSpec())]

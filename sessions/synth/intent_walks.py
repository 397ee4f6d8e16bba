"""Walks whose speed changes on purpose: the virtual cohort's data for seed 001's intent filter.

Protocol (seed 001 Sec. III-A): the walker is at a steady, self-selected speed when a command to speed up
(SU) or slow down (SD) is issued at a known step (the paper's command steps are 7 and 8), three trials of
each per subject; and self-paced walks where the walker changes speed at steps of their own choosing.
The cohort walks on a self-paced treadmill (the belt follows the walker), so the walker's speed is theirs,
as overground. Every sample carries what the filter reads (:func:`gaitscope.sessions.synth.sensors.device_channels`:
centre of mass relative to the stance foot, both hip angles, both feet's forces, the last step length) and
the ground truth is in :class:`IntentTrial` (desired speed per stride, command time and direction).

How intent shows before speed (sources and argument in ``docs/cohort.md``, "Speed changes"):

- the walker's **desired speed** steps to the new value in the stride the command falls in (the
  transition starts within half a step of a treadmill speed change, Rodman and Martin's kinematic
  model study; a verbal command adds a reaction time of the same order);
- the **speed** approaches the desired one step by step, first order with time constant
  ``speed_tau_steps`` (1.5 steps, so the change is 86 % done after 3 steps: transitions last 2-3 steps);
- the **step length leads**: each stride is as long as a steady stride at the speed
  ``v + step_lead (v_d - v)``, part of the way from the current to the desired speed, so step length
  converges in fewer steps than speed (Rodman and Martin 2020) and a step's length tells of the speed to
  come (seed 001 Fig. 4, Kuo 2001);
- stride-to-stride **speed noise** with coefficient of variation ``speed_cv`` on top of the cohort's own
  stride-time variation (whose stride length varies at constant speed).

Resolution is a stride (both steps of a stride share its speed and length scale); within a stride the
curves and the centre-of-mass speed morph from the previous stride's, so nothing jumps. The numbers above
are choices argued from the literature, fixed before the seed 001 reproduction was run and not changed
after (``docs/cohort.md`` reports the reproduction at other values of ``step_lead`` too).
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
from gaitscope.sessions.synth.normative import at_speed, normative

__all__ = [
    "IntentProtocol",
    "IntentTrial",
    "commanded_trial",
    "intent_trials",
    "self_paced_trial",
    "speed_profile",
    "steady_trial",
]

G = 9.81


@dataclass(frozen=True)
class IntentProtocol:
    """The speed-change walks of one cohort (defaults: seed 001's protocol, ``docs/cohort.md``).

    Attributes:
        strides_before: steady strides before the command (4: the command falls at step 8).
        strides_after: strides from the command on.
        trials_per_direction: SU and SD trials per subject (seed 001: 3 each).
        speed_range_m_s: the trial's self-selected speed before the change, uniform in this range.
        change_range_m_s: size of the commanded change, uniform in this range (seed 001 notes changes
            below ~0.15 m/s are hard to see in step length).
        self_paced_strides: length of a self-paced walk; its changes come every 4 to 8 strides.
        speed_tau_steps: time constant of the speed's approach to the desired speed, in steps.
        step_lead: how far toward the desired speed a stride's length already is (0: none, 1: all).
        speed_cv: stride-to-stride coefficient of variation of the speed.
        rate_hz: sample rate of the sensor frames.
        seed: the walks' random streams derive from it (each trial its own).
    """

    strides_before: int = 4
    strides_after: int = 6
    trials_per_direction: int = 3
    speed_range_m_s: tuple[float, float] = (0.9, 1.3)
    change_range_m_s: tuple[float, float] = (0.15, 0.4)
    self_paced_strides: int = 30
    speed_tau_steps: float = 1.5
    step_lead: float = 0.5
    speed_cv: float = 0.02
    rate_hz: float = 100.0
    seed: int = 20210401

    def __post_init__(self) -> None:
        if self.strides_before < 2 or self.strides_after < 2:
            raise ValueError("strides_before and strides_after must be >= 2")
        if not (self.speed_tau_steps > 0 and 0.0 <= self.step_lead <= 1.0 and 0.0 <= self.speed_cv < 0.2):
            raise ValueError("need speed_tau_steps > 0, 0 <= step_lead <= 1 and 0 <= speed_cv < 0.2")
        lo, hi = self.speed_range_m_s
        if not 0.3 <= lo <= hi <= 2.0:
            raise ValueError(f"speed_range_m_s must lie in 0.3..2.0 m/s, got {self.speed_range_m_s}")


@dataclass(frozen=True)
class IntentTrial:
    """One walk and its ground truth.

    Attributes:
        subject: the walker.
        name: "SU-01", "SD-02", "SP-01" (self-paced).
        direction: +1 speed up, -1 slow down, 0 self-paced (several changes).
        command_time_s: when the command was issued (NaN for self-paced walks).
        stride_start_s: start time of each stride (ipsilateral heel strike).
        desired_m_s: the walker's desired speed in each stride.
        speed_m_s: the walker's mean speed in each stride.
        sensors: the sensor frame at ``rate_hz`` (channel names of :mod:`gaitscope.sessions.schema`'s sensor frame,
            plus ``gt_*`` ground truth).
    """

    subject: SubjectParams
    name: str
    direction: int
    command_time_s: float
    stride_start_s: np.ndarray
    desired_m_s: np.ndarray
    speed_m_s: np.ndarray
    sensors: pd.DataFrame

    def desired_at(self, t: np.ndarray) -> np.ndarray:
        """The desired speed at times ``t`` (that of the stride each falls in)."""
        i = np.clip(np.searchsorted(self.stride_start_s, t, side="right") - 1, 0, len(self.desired_m_s) - 1)
        return self.desired_m_s[i]


def speed_profile(
    desired: np.ndarray, v0: float, leg_length_m: float, protocol: IntentProtocol, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Per-stride speed and stride-length scale for a walker whose desired speed per stride is ``desired``.

    Speed: ``v_k = v_(k-1) + a (d_k - v_(k-1))`` with ``a = 1 - exp(-2 / speed_tau_steps)`` (two steps a
    stride), times ``1 + speed_cv eps_k``. Length: the steady stride length at ``v_k + step_lead (d_k - v_k)``
    over that at ``v_k`` (Schwartz 2008's step length in dimensionless speed, as the cohort's).
    """
    a = 1.0 - math.exp(-2.0 / protocol.speed_tau_steps)
    v = np.empty(len(desired))
    prev = v0
    for k, d in enumerate(desired):
        prev = prev + a * (float(d) - prev)
        v[k] = prev
    v = v * (1.0 + protocol.speed_cv * rng.standard_normal(len(v)))
    lead = v + protocol.step_lead * (np.asarray(desired, dtype=np.float64) - v)
    return v, _steady_step(lead, leg_length_m) / _steady_step(v, leg_length_m)


def _steady_step(v: np.ndarray, leg_length_m: float) -> np.ndarray:
    """Schwartz's step length per leg length at speed ``v`` (the subject's scale cancels in the ratio
    ``speed_profile`` takes)."""
    scale = math.sqrt(G * leg_length_m)
    return np.array([float(at_speed(normative().step, max(float(x), 0.05) / scale)) for x in v])


def _trial(
    subject: SubjectParams,
    name: str,
    direction: int,
    desired: np.ndarray,
    v0: float,
    command_stride: int | None,
    protocol: IntentProtocol,
    rng: np.random.Generator,
) -> IntentTrial:
    speed, scale = speed_profile(desired, v0, subject.leg_length_m, protocol, rng)
    walk = generate_walk(subject, [(float(v), 0.0, 1) for v in speed], rng, stride_scale=scale)
    starts = walk.loc[walk[s.PHASE_IPSI] == 0.0, s.TIME_S].to_numpy(np.float64)
    uniform = resample_walk(walk, protocol.rate_hz)
    sensors = simulate_sensors(uniform, SensorNoise(), rng)
    command = float(starts[command_stride]) if command_stride is not None else math.nan
    return IntentTrial(subject, name, direction, command, starts, np.asarray(desired, np.float64), speed, sensors)


def _rng(protocol: IntentProtocol, subject: SubjectParams, kind: int, index: int) -> np.random.Generator:
    key = (1, int(subject.code[2:]), kind, index)
    return np.random.default_rng(np.random.SeedSequence(protocol.seed, spawn_key=key))


def commanded_trial(subject: SubjectParams, direction: int, index: int, protocol: IntentProtocol) -> IntentTrial:
    """A commanded speed-up (``direction`` +1) or slow-down (-1): steady at the trial's self-selected speed
    for ``strides_before`` strides, then the new desired speed from the command stride on."""
    if direction not in (1, -1):
        raise ValueError(f"direction must be +1 or -1, got {direction}")
    rng = _rng(protocol, subject, 0 if direction > 0 else 1, index)
    v0 = float(rng.uniform(*protocol.speed_range_m_s))
    change = direction * float(rng.uniform(*protocol.change_range_m_s))
    n = protocol.strides_before + protocol.strides_after
    desired = np.full(n, v0)
    desired[protocol.strides_before :] = max(v0 + change, 0.4)
    name = f"{'SU' if direction > 0 else 'SD'}-{index + 1:02d}"
    return _trial(subject, name, direction, desired, v0, protocol.strides_before, protocol, rng)


def self_paced_trial(subject: SubjectParams, index: int, protocol: IntentProtocol) -> IntentTrial:
    """A self-paced walk: the desired speed changes every 4 to 8 strides, by a change drawn as the
    commanded ones' with a random sign, kept within 0.6-1.6 m/s."""
    rng = _rng(protocol, subject, 2, index)
    v = float(rng.uniform(*protocol.speed_range_m_s))
    desired = np.empty(protocol.self_paced_strides)
    k = 0
    while k < len(desired):
        hold = int(rng.integers(4, 9))
        desired[k : k + hold] = v
        k += hold
        step = float(rng.uniform(*protocol.change_range_m_s))
        v = v + step if (v - step < 0.6 or (rng.random() < 0.5 and v + step <= 1.6)) else v - step
    return _trial(subject, f"SP-{index + 1:02d}", 0, desired, float(desired[0]), None, protocol, rng)


def intent_trials(
    protocol: IntentProtocol | None = None, spec: CohortSpec | None = None, self_paced: int = 1
) -> list[IntentTrial]:
    """Every cohort subject's commanded SU and SD trials and ``self_paced`` self-paced walks (defaults:
    ``IntentProtocol()`` and the cohort's ``CohortSpec()``)."""
    protocol = protocol or IntentProtocol()
    out: list[IntentTrial] = []
    for subject in make_subjects(spec or CohortSpec()):
        for direction in (1, -1):
            out += [commanded_trial(subject, direction, i, protocol) for i in range(protocol.trials_per_direction)]
        out += [self_paced_trial(subject, i, protocol) for i in range(self_paced)]
    return out


def steady_trial(subject: SubjectParams, index: int, protocol: IntentProtocol, minutes: float = 5.0) -> IntentTrial:
    """A steady walk of about ``minutes`` at one self-selected speed (drawn as the commanded trials' first
    speed): what a call of a speed change should stay quiet on. Its stride-to-stride speed noise is the
    protocol's ``speed_cv``, as in every other walk."""
    if not 0.1 <= minutes <= 60.0:
        raise ValueError(f"minutes must lie in 0.1..60, got {minutes}")
    rng = _rng(protocol, subject, 3, index)
    v0 = float(rng.uniform(*protocol.speed_range_m_s))
    stride_s = 2.0 * float(_steady_step(np.array([v0]), subject.leg_length_m)[0]) * subject.leg_length_m / v0
    desired = np.full(max(2, math.ceil(60.0 * minutes / stride_s)), v0)
    return _trial(subject, f"ST-{index + 1:02d}", 0, desired, v0, None, protocol, rng)

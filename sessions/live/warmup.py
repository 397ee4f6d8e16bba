"""Compile every numba kernel a live session can call before the server answers (:func:`warm_up`).

numba compiles a kernel on its first call: on a cold cache (a fresh install, or a cache folder the server
cannot write) that is 15-25 s of one core for the GP-EKF's kernels alone, and as long again for the phase
EKF's. Done inside a session's first sample, it stalled the session's event loop for that long: in a fresh
clone a device streaming to a ``gp_ekf`` stack waited 18 s for its first torque and gave up
(``tests/e2e/test_gp_learning.py``). So the server runs every registered estimator, opt-in ones included,
over a short synthetic walk at start-up, before it answers, and a session only ever calls compiled code.
``tests/sessions/live/test_warmup.py`` checks, in a fresh process, that every kernel of ``estimators`` that
a session's estimators call has been compiled by it.

The walk is not a gait anyone walks: each channel a smooth periodic signal of its kind (angles, rates,
forces, IMU axes), heel strikes once a second, then standing still and a gap, so that each estimator passes
through its stance, swing, hold and restart branches. What it estimates is thrown away; what it costs is not:
each estimator's step is timed over the walk's last second, when everything it calls is compiled, and
:func:`warm_up` returns the medians, the time per sample of each estimator on this server (``GET /api/estimators``
shows them when a session's estimators are chosen).
"""

from __future__ import annotations

import math
import time
from typing import Final

import numpy as np

from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.estimators.protocol import HEEL_STRIKE, input_names
from gaitscope.sessions.estimation import DEFAULT_PERIOD, FrameEstimator
from gaitscope.sessions.registry import ESTIMATORS, StackContext, Unavailable
from gaitscope.sessions.schema import SensorFrame, SessionSettings

__all__ = ["warm_up"]

_RATE: Final = 100.0  # Hz
_WALK_S: Final = 3.5  # s of walking: three heel strikes, so that each filter has completed a stride
_STAND_S: Final = 1.0  # s standing still after it (the holds), then a gap of 2 s (the restarts)
_TIMED: Final = 100  # the stream's last samples (walking again after the gap), each estimator's step timed


def _value(channel: str, t: float, walking: bool) -> float:
    """A plausible value of ``channel`` at ``t``: a 1 Hz gait-like wave while walking, constant standing."""
    w = 2.0 * math.pi * t if walking else 0.0
    s, c = math.sin(w), math.cos(w)
    if channel == HEEL_STRIKE:
        return float(walking and round(t * _RATE) % round(_RATE) == 0)
    if "accel" in channel:
        return 9.81 + 2.0 * s if channel.endswith("x_m_s2") else 1.0 * c
    if "gyro" in channel or channel.endswith("_dps"):
        return 120.0 * c
    if channel.endswith("_deg"):
        return 25.0 * s
    if channel.endswith("_N"):
        return 700.0 * max(0.0, s)
    if channel.startswith("foot_contact"):
        return float(s >= 0.0)
    if channel == "heel_up_m":
        return -0.85 + 0.05 * s
    if channel.startswith("com_up"):
        return 0.9 + 0.02 * s
    return 0.2 * c  # positions (m) and speeds (m/s), current (A), torque (N m)


def _stream() -> list[tuple[float, bool]]:
    """Session times of the synthetic walk and whether the walker is walking at each."""
    walk = [(k / _RATE, True) for k in range(round(_WALK_S * _RATE))]
    stand = [(_WALK_S + k / _RATE, False) for k in range(round(_STAND_S * _RATE))]
    after_gap = [(_WALK_S + _STAND_S + 2.0 + k / _RATE, True) for k in range(round(1.5 * _RATE))]
    return walk + stand + after_gap


def warm_up(model: TrainedModel) -> dict[str, float]:
    """Run a throw-away session's frame path and every registered estimator (:data:`ESTIMATORS`, opt-in
    ones included; those the model cannot build are skipped) over the synthetic walk, so that every
    compiled kernel they call is built (or loaded from numba's cache).

    Returns:
        By estimator name (those built, in registry order), the median time of its ``step`` over the walk's
        last :data:`_TIMED` samples, after everything it calls is compiled: its cost per sample on this
        machine, in microseconds (the input vector made beforehand, so only the step is timed).
    """
    stream = _stream()
    frames = FrameEstimator(model, 0.9, 75.0, SessionSettings(), DEFAULT_PERIOD)
    for k, (t, walking) in enumerate(stream):
        channels = ("foot_angle_deg", "shank_angle_deg", "heel_forward_m", "heel_up_m", HEEL_STRIKE)
        frames.step(SensorFrame.model_validate({"seq": k, "t": t, **{c: _value(c, t, walking) for c in channels}}), 0)
    fmap = model.fingerprints
    fingerprint = None if fmap is None else (0.0,) * fmap.n_components
    ctx = StackContext(model, 0.9, 75.0, 1.0 / _RATE, fingerprint=fingerprint)
    timed_from = len(stream) - _TIMED
    costs: dict[str, float] = {}
    for name, make in ESTIMATORS.items():
        try:
            est = make(ctx)
        except Unavailable:
            continue
        names = input_names(est)
        ns: list[int] = []
        for k, (t, walking) in enumerate(stream):
            z = np.array([_value(c, t, walking) for c in names], dtype=np.float64)
            start = time.perf_counter_ns()
            est.step(t, z)
            if k >= timed_from:
                ns.append(time.perf_counter_ns() - start)
        costs[name] = round(float(np.median(ns)) / 1e3, 2)
    return costs

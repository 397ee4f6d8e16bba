"""The intent estimator's row of ``gaitscope bench``: per-sample cost of :class:`IntentEstimator`
on a simulated walk, between events and at events, against a baseline measured in the same run.

Issue #9 asks for the bookkeeping of a sample between events (touchdown, mid-stance) to cost at most 2 us.
The walk is the virtual cohort's default subject at 1.0 then 1.3 m/s (:func:`sessions.synth.trials.sensor_trial`),
fed as the stack feeds it, without contact flags (so that the events come from the foot forces, the costlier
path). An untimed pass marks the samples at which an event handler ran; then the estimator and the baseline
are timed sample by sample (``time.perf_counter_ns`` around each ``step``), each in a pass of its own, and
split by that mark.

Baseline (:class:`ReferenceIntent`): seed 001 written the direct way, as a general-purpose library would have
it: filterpy's ``KalmanFilter`` for the touchdown update (eq. 2's ``Q_T`` folded into the measurement noise,
``R + q_T H H^T``) and for the propagation and mid-stance update (eqs. 5-9), the events detected by numpy
indexing of each sample (as :class:`IntentEstimator` did before issue #9). It has none of the estimator's
guards (hysteresis, holding, implausible values) and reads the intent at mid-stance, so on a clean walk both
see the same events and their outputs are compared with the estimator set up the same way (intent at
mid-stance, coded from the first step); the timed estimator is the one sessions run (intent at touchdown).
The ratio understates nothing between events and slightly flatters the baseline at them.
Nothing here runs at run time.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np
from filterpy.kalman import KalmanFilter
from numpy.typing import NDArray

from gaitscope.estimators.intent import COHORT, BKFConfig, D
from gaitscope.estimators.intent_estimator import IntentEstimator
from gaitscope.estimators.protocol import input_names
from gaitscope.sessions.offline.timing import step_times
from gaitscope.sessions.synth.trials import sensor_trial

__all__ = ["ReferenceIntent", "intent_cost", "walk_inputs"]

Array = NDArray[np.float64]


class ReferenceIntent:
    """The baseline: seed 001 on filterpy's ``KalmanFilter`` (see the module docstring); ``step(t, z)`` as
    :meth:`IntentEstimator.step`, on a clean walk."""

    def __init__(self, leg_length: float, config: BKFConfig = COHORT, contact_fraction: float = 0.05):
        self.leg, self.c, self.fraction = leg_length, config, contact_fraction
        self.kf = KalmanFilter(dim_x=7, dim_z=6)
        self.kf.F, self.kf.Q = D.copy(), np.diag(config.q_m)
        self.started = self.touched = self.double = False
        self.max_force, self.hip_diff, self.last_vxd = 0.0, math.nan, 0.0
        self.out = np.zeros(5)

    def step(self, t: float, z: Array) -> Array:
        f_i, f_c = z[6], z[7]
        for f in (f_i, f_c):
            if f > self.max_force:  # NaN compares False
                self.max_force = f
        limit = self.fraction * self.max_force
        double = bool(self.max_force > 0 and f_i > limit and f_c > limit)
        if double and not self.double:
            self._touchdown(float(z[8]))
        self.double = double
        diff = z[4] - z[5]
        if not np.isnan(diff):
            if not np.isnan(self.hip_diff) and (diff > 0) != (self.hip_diff > 0):
                self._midstance(z[[0, 9, 1, 2, 10, 3]])  # forward, lateral, up; their velocities
            self.hip_diff = diff
        return self.out.copy()

    def _touchdown(self, length: float) -> None:
        if not self.started or self.touched or not math.isfinite(length):
            return
        k1, k2, k3 = self.c.kappa
        H = np.zeros((1, 7))
        H[0, 3], H[0, 6] = k1 - k2, k2
        R = np.array([[self.c.r_t[0]]]) + self.c.q_t * H @ H.T
        self.kf.update(np.array([length - k3 * self.leg]), R=R, H=H)
        self.touched = True

    def _midstance(self, com: Array) -> None:
        kf = self.kf
        if not self.started:
            kf.x = np.array([*com, com[3]])
            kf.P = np.diag(self.c.p0)
            self.started, self.touched, self.last_vxd = True, False, float(com[3])
            self.out[:] = (com[3], 0.0, 0.0, 0.0, com[3])
            return
        kf.predict()
        ok = np.isfinite(com)
        kf.update(com[ok], R=np.diag(np.asarray(self.c.r_m)[ok]), H=np.eye(6, 7)[ok])
        vxd = float(kf.x[6])
        intent = vxd - self.last_vxd if self.touched else 0.0
        confidence = abs(intent) / math.sqrt(max(float(kf.P[6, 6]), 1e-18)) if self.touched else 0.0
        code = 0.0
        if abs(intent) >= 0.01 and confidence >= 1.0:
            code = 1.0 if intent > 0 else -1.0
        self.out[:] = (vxd, intent, code, confidence, float(kf.x[3]))
        self.last_vxd, self.touched = vxd, False


def walk_inputs(strides: int = 30) -> tuple[list[float], Array, float]:
    """Session times, the intent estimator's inputs ``(n, 14)`` (no contact flags) and the leg length of a
    walk of ``strides`` strides at 1.0 m/s then as many at 1.3, at 100 Hz."""
    sensors, leg, _ = sensor_trial([(1.0, 0.0, strides), (1.3, 0.0, strides)], rate_hz=100.0)
    missing = np.full(len(sensors), np.nan)
    names = input_names(IntentEstimator(leg))
    z = np.column_stack([sensors[c].to_numpy(np.float64) if c in sensors else missing for c in names])
    z[:, names.index("foot_contact")] = z[:, names.index("foot_contact_contra")] = np.nan
    return sensors["time_s"].tolist(), z, leg


def _event_samples(est: IntentEstimator, t: list[float], z: Array) -> NDArray[np.bool_]:
    """Which samples ran an event handler (touchdown or mid-stance), from an untimed pass."""
    hit = [False]
    for name in ("_touchdown", "_midstance"):
        handler = getattr(est, name)

        def marked(*args: object, _h: Callable[..., None] = handler) -> None:
            hit[0] = True
            _h(*args)

        setattr(est, name, marked)
    mask = np.zeros(len(t), dtype=bool)
    for k, tk in enumerate(t):
        hit[0] = False
        est.step(tk, z[k])
        mask[k] = hit[0]
    return mask


def intent_cost(strides: int = 30) -> dict[str, float]:
    """Median and p95 (us) of the estimator's and the baseline's ``step``, between events and at events,
    with the ratios of the medians (baseline / estimator) and the largest output difference.

    Returns:
        ``samples``, ``events``, ``between_median_us``, ``between_p95_us``, ``events_median_us``,
        ``events_p95_us``, the same with ``ref_`` in front for the baseline, ``between_ratio``,
        ``events_ratio`` and ``max_output_diff``.
    """
    t, z, leg = walk_inputs(strides)
    events = _event_samples(IntentEstimator(leg), t, z)
    ours, ref = step_times(IntentEstimator(leg).step, t, z), step_times(ReferenceIntent(leg).step, t, z)
    out: dict[str, float] = {"samples": float(len(t)), "events": float(events.sum())}
    for prefix, ns in (("", ours), ("ref_", ref)):
        for part, mask in (("between", ~events), ("events", events)):
            out[f"{prefix}{part}_median_us"] = float(np.median(ns[mask]) / 1e3)
            out[f"{prefix}{part}_p95_us"] = float(np.percentile(ns[mask], 95) / 1e3)
    for part in ("between", "events"):
        out[f"{part}_ratio"] = out[f"ref_{part}_median_us"] / out[f"{part}_median_us"]
    # agreement: the estimator set up as the baseline reads its intent (at mid-stance, coded from the first step)
    same = replace(COHORT, intent_at="midstance")
    a = IntentEstimator(  # the baseline's class and confidence
        leg, same, deadband_m_s=0.01, min_confidence=1.0, recover_steps=0, episodes=None, confidence_scale=1.0
    )
    b = ReferenceIntent(leg, same)
    out["max_output_diff"] = max(float(np.abs(a.step(tk, z[k]) - b.step(tk, z[k])).max()) for k, tk in enumerate(t))
    return out

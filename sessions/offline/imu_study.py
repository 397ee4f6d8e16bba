"""The IMU front end on the virtual cohort: which orientation filter turns its simulated IMUs into angles.

``gaitscope crossval --study imu``. Each of ``subjects`` cohort subjects walks the treadmill protocol
(seed 000 III-E, :data:`~gaitscope.sessions.schema.TREADMILL_PROTOCOL`) at 100 Hz through the cohort's simulated
MPU-9250s (:mod:`gaitscope.sessions.synth.imu`: noise, bias up to 5 deg/s, scale, mounting misalignment, ADC); every
filter turns each leg IMU's raw readings into the segment's sagittal angle, compared with the true angle:

- ``cf``: :class:`gaitscope.estimators.imu_frontend.ImuFrontEnd` (gated complementary filter, tracked gyro bias,
  foot-flat resets on the feet), the live default;
- ``fusion``: the same front end with x-io's Fusion AHRS (``imufusion``) as its filter;
- ``madgwick``, ``mahony``: the ``ahrs`` package's filters (defaults, 100 Hz; when installed) on the bias-tracked gyro,
  the angle from their gravity vector (the first ``ahrs_subjects`` subjects: they cost 40-50 us a sample);
- ``gyro``: the integrated gyro alone, ``accel``: the accelerometer's inclination alone (baselines).

Per segment and condition (speed, incline): RMSE (deg) and the offset-free RMSE (the error's sd: what is
left once a standing calibration removed the constant offset), skipping each trial's first 10 s (the bias
tracker's settling); cost per sample (us, wall clock, this machine). The foot front end's toe-off is
reported as the mean true phase at the detected toe-offs.
"""

from __future__ import annotations

import importlib.util
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Final

import numpy as np
import pandas as pd

from gaitscope.estimators.imu_frontend import ImuFrontEnd, imu_inputs
from gaitscope.sessions import schema as s
from gaitscope.sessions.schema import TREADMILL_PROTOCOL
from gaitscope.sessions.synth.cohort import (
    CohortSpec,
    SensorNoise,
    generate_walk,
    make_subjects,
    resample_walk,
    simulate_sensors,
)

__all__ = ["METHODS", "SEGMENTS", "ImuStudy", "run_study", "to_markdown", "trial"]

#: The leg segments compared, with the cohort's true-angle column.
SEGMENTS: Final = {"foot": s.FOOT_ANGLE, "shank": s.SHANK_ANGLE, "thigh": s.THIGH_ANGLE}
METHODS: Final = ("cf", "fusion", "madgwick", "mahony", "gyro", "accel")
_SETTLE_S: Final = 10.0
#: ``ahrs`` is a comparison only (not a dependency): its rows are left out where it is not installed.
_HAS_AHRS: Final = importlib.util.find_spec("ahrs") is not None
_RATE_HZ: Final = 100.0


@dataclass(frozen=True)
class ImuStudy:
    """Errors per (method, segment, speed, incline): one row per trial and condition (``errors``), and
    per method and segment the cost per sample (us) and, for the foot, the mean true phase at toe-off."""

    errors: pd.DataFrame  #: method, segment, subject, speed, incline, n, rmse_deg, sd_deg
    cost_us: dict[tuple[str, str], float]
    toe_off_phase: float


def trial(subject: int, seed: int) -> tuple[pd.DataFrame, pd.DataFrame]:
    """A subject's treadmill protocol as :func:`gaitscope.sessions.synth.trials.sensor_trial` simulates it, with the
    clean walk it came from (the true angles): ``(sensors, walk)``, row for row."""
    subj = make_subjects(CohortSpec())[subject]
    rng = np.random.default_rng(seed)
    walk = resample_walk(generate_walk(subj, TREADMILL_PROTOCOL, rng), _RATE_HZ)
    sensors = simulate_sensors(walk, SensorNoise(), rng)
    if len(sensors) != len(walk):
        raise RuntimeError("the resampled walk has repeated instants: the true angles would not line up")
    return sensors, walk


def _front_end(method: str) -> Callable[[str, np.ndarray, np.ndarray], np.ndarray]:
    def run(segment: str, t: np.ndarray, z: np.ndarray) -> np.ndarray:
        est = ImuFrontEnd(segment, method="fusion" if method == "fusion" else "cf")
        out = np.empty((len(t), len(est.outputs)))
        for i in range(len(t)):
            out[i] = est.step(float(t[i]), z[i])
        return out

    return run


def _ahrs(method: str, t: np.ndarray, z: np.ndarray) -> np.ndarray:
    from ahrs.filters import Madgwick, Mahony

    f = Madgwick(frequency=_RATE_HZ) if method == "madgwick" else Mahony(frequency=_RATE_HZ)
    q = np.array([1.0, 0.0, 0.0, 0.0])
    bias = z[0, :3].copy()
    out = np.empty(len(t))
    for i in range(len(t)):
        bias += (z[i, :3] - bias) / (_RATE_HZ * 10.0)
        g = np.radians(z[i, :3] - bias)
        q = f.updateIMU(q, np.array([g[0], -g[2], g[1]]), np.array([z[i, 3], -z[i, 5], z[i, 4]]))
        w, x, y, zz = q
        out[i] = math.degrees(math.atan2(2 * (x * zz - w * y), w * w - x * x - y * y + zz * zz))
    return out


def _baseline(method: str, t: np.ndarray, z: np.ndarray) -> np.ndarray:
    incl = np.degrees(np.arctan2(z[:, 3], z[:, 4]))
    if method == "accel":
        return incl
    dt = np.diff(t, prepend=t[0])
    return incl[0] + np.cumsum((z[:, 2] - np.mean(z[:, 2])) * dt)  # the trial's mean rate as its bias


def run_study(subjects: int = 3, ahrs_subjects: int = 1, seed: int = 7) -> ImuStudy:
    """The comparison on ``subjects`` cohort subjects (seeds ``seed + subject``)."""
    rows = []
    cost: dict[tuple[str, str], list[float]] = {}
    toe = []
    for subject in range(subjects):
        sensors, walk = trial(subject, seed + subject)
        t = sensors[s.REPLAY_TIME].to_numpy(np.float64)
        speed, incline = walk[s.SPEED].to_numpy(), walk[s.INCLINE].to_numpy()
        keep = t - t[0] >= _SETTLE_S
        phase = sensors["gt_phase"].to_numpy(np.float64)
        for segment, column in SEGMENTS.items():
            truth = np.degrees(walk[column].to_numpy(np.float64))
            z = sensors[list(imu_inputs(segment))].to_numpy(np.float64)
            for method in METHODS:
                if method in ("madgwick", "mahony") and (subject >= ahrs_subjects or not _HAS_AHRS):
                    continue
                start = time.perf_counter()
                if method in ("cf", "fusion"):
                    out = _front_end(method)(segment, t, z)
                    angle = out[:, 0]
                    if segment == "foot" and method == "cf":
                        toe.extend(phase[(out[:, 4] > 0.5) & keep])
                elif method in ("madgwick", "mahony"):
                    angle = _ahrs(method, t, z)
                else:
                    angle = _baseline(method, t, z)
                cost.setdefault((method, segment), []).append((time.perf_counter() - start) / len(t) * 1e6)
                err = (angle - truth + 180.0) % 360.0 - 180.0
                for (v, r), idx in (
                    pd.DataFrame({"v": speed, "r": incline}).loc[keep].groupby(["v", "r"]).groups.items()
                ):
                    e = err[np.asarray(idx)]
                    rows.append((method, segment, subject, float(v), float(r), len(e),
                                 float(np.sqrt(np.mean(e**2))), float(np.std(e))))  # fmt: skip
    errors = pd.DataFrame(rows, columns=["method", "segment", "subject", "speed", "incline", "n", "rmse_deg", "sd_deg"])
    return ImuStudy(errors, {k: float(np.median(v)) for k, v in cost.items()}, float(np.mean(toe)) if toe else math.nan)


def _pooled(e: pd.DataFrame) -> tuple[float, float]:
    w = e["n"].to_numpy(np.float64)
    return (
        float(np.sqrt(np.sum(w * e["rmse_deg"] ** 2) / w.sum())),
        float(np.sqrt(np.sum(w * e["sd_deg"] ** 2) / w.sum())),
    )


def to_markdown(study: ImuStudy) -> str:
    """The comparison as Markdown: per method and segment over all conditions, then ``cf`` per condition."""
    e = study.errors
    n_subj = e.loc[e["method"] == "cf", "subject"].nunique()
    lines = [
        f"Sagittal angle error against the true segment angle, {n_subj} cohort subjects on the treadmill "
        "protocol at 100 Hz (first 10 s skipped); RMSE / offset-free RMSE (the error's sd) in deg, pooled "
        "over conditions; cost in us per sample (median, this machine).",
        "",
        "| method | subjects | " + " | ".join(f"{g} RMSE / sd" for g in SEGMENTS) + " | us / sample |",
        "|---|---|" + "---|" * len(SEGMENTS) + "---|",
    ]
    for method in METHODS:
        m = e[e["method"] == method]
        if m.empty:
            continue
        cells = [f"{a:.2f} / {b:.2f}" for a, b in (_pooled(m[m["segment"] == g]) for g in SEGMENTS)]
        us = np.median([study.cost_us[(method, g)] for g in SEGMENTS])
        lines.append(f"| {method} | {m['subject'].nunique()} | " + " | ".join(cells) + f" | {us:.1f} |")
    header = "| speed (m/s) | incline (deg) | " + " | ".join(SEGMENTS) + " |"
    lines += ["", "`cf` per condition (RMSE / sd, deg):", "", header, "|---|---|" + "---|" * len(SEGMENTS)]
    cf = e[e["method"] == "cf"]
    for (v, r), c in cf.groupby(["speed", "incline"]):
        cells = [f"{a:.2f} / {b:.2f}" for a, b in (_pooled(c[c["segment"] == g]) for g in SEGMENTS)]
        lines.append(f"| {v:g} | {r:g} | " + " | ".join(cells) + " |")
    lines += ["", f"Foot toe-off (`cf`): mean true phase at the detected toe-offs {study.toe_off_phase:.3f}."]
    return "\n".join(lines) + "\n"

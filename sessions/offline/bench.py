"""``gaitscope bench``: speed of the phase EKF, of replay and of cross-validation, measured in one run.

1. Per-sample cost (predict + update through the Python interface, ``time.perf_counter_ns`` around each
   sample) of :class:`~estimators.phase_ekf.PhaseEKF` against the baseline
   :class:`~estimators.reference.ReferencePhaseEKF` (filterpy's ``ExtendedKalmanFilter`` with the same
   model in vectorised numpy), on the same simulated trial with the shipped model; both filters run in
   lock step and the largest state and covariance difference over every sample is reported.
2. Replay throughput of a 10-minute 100 Hz trial through the command-line path (CSV in, CSV out).
3. Wall time of the full leave-one-subject-out cross-validation.

Targets (issue #2): gaitscope >= 20x faster than the reference and < 10 us per sample; states agree
to 1e-9; cross-validation under 5 minutes on 2 cores.
"""

from __future__ import annotations

import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

from estimators.phase_ekf import PhaseEKF
from estimators.pipeline import PipelineConfig
from estimators.reference import ReferencePhaseEKF
from sessions.formats.models import default_model_path, load_model
from sessions.offline.replay import measurements, replay_file
from sessions.synth.trials import minutes_schedule, replay_columns, replay_input, sensor_trial


def _percentiles(ns: np.ndarray) -> tuple[float, float]:
    return float(np.median(ns) / 1e3), float(np.percentile(ns, 95) / 1e3)


def ekf_cost(reference_samples: int) -> dict[str, float]:
    """Per-sample cost of both filters and their largest disagreement."""
    model, _ = load_model(default_model_path())
    sensors, leg, _ = sensor_trial()
    data = replay_input(sensors)
    z = measurements(data)
    dts = np.diff(data.time_s, prepend=data.time_s[0] - 0.01)
    fast = PhaseEKF(model.coef, model.noise, leg)
    ref = ReferencePhaseEKF(model.coef, model.noise, leg)
    n_ref = min(reference_samples, len(z))
    t_fast = np.empty(len(z), dtype=np.int64)
    t_ref = np.empty(n_ref, dtype=np.int64)
    dx = dp = 0.0
    clock = time.perf_counter_ns
    for k in range(n_ref):
        t0 = clock()
        fast.predict(dts[k])
        fast.update(z[k])
        t1 = clock()
        ref.predict(dts[k])
        ref.update(z[k])
        t2 = clock()
        t_fast[k], t_ref[k] = t1 - t0, t2 - t1
        diff = np.abs(fast.x - ref.x)
        diff[0] = min(diff[0], 1 - diff[0])
        dx = max(dx, float(diff.max()))
        dp = max(dp, float(np.abs(fast.P - ref.P).max()))
    for k in range(n_ref, len(z)):
        t0 = clock()
        fast.predict(dts[k])
        fast.update(z[k])
        t_fast[k] = clock() - t0
    f50, f95 = _percentiles(t_fast)
    r50, r95 = _percentiles(t_ref)
    return {
        "samples": float(len(z)),
        "reference_samples": float(n_ref),
        "fast_median_us": f50,
        "fast_p95_us": f95,
        "ref_median_us": r50,
        "ref_p95_us": r95,
        "speedup_median": r50 / f50,
        "max_state_diff": dx,
        "max_cov_diff": dp,
    }


def replay_throughput(minutes: float = 10.0) -> dict[str, float]:
    """Samples per second of ``gaitscope replay`` on a ``minutes`` long 100 Hz trial."""
    sensors, leg, mass = sensor_trial(minutes_schedule(minutes), rate_hz=100.0)
    sensors = sensors[sensors["time_s"] < sensors["time_s"].iloc[0] + minutes * 60]
    model, _ = load_model(default_model_path())
    with tempfile.TemporaryDirectory() as d:
        src, dst = Path(d) / "trial.csv", Path(d) / "out.csv"
        replay_columns(sensors).to_csv(src, index=False, float_format="%.6f")
        t0 = time.perf_counter()
        summary = replay_file(src, dst, model, PipelineConfig(leg_length=leg, body_mass_kg=mass))
        wall = time.perf_counter() - t0
    return {"samples": float(summary.samples), "wall_s": wall, "samples_per_s": summary.samples / wall}


def crossval_time() -> float:
    from sessions.offline.crossval import crossvalidate

    t0 = time.perf_counter()
    crossvalidate()
    return time.perf_counter() - t0


def run_bench(crossval: bool = True, reference_samples: int = 3000) -> dict[str, float]:
    """Measure and print everything; returns the numbers."""
    cpu = platform.processor() or platform.machine()
    print(f"machine: {cpu}, {os.cpu_count()} cores, Python {platform.python_version()}")
    e = ekf_cost(reference_samples)
    print("phase EKF, per sample (predict + update), default model, 6 channels:")
    for name, key, n in (
        ("gaitscope PhaseEKF", "fast", "samples"),
        ("filterpy reference", "ref", "reference_samples"),
    ):
        med, p95 = e[f"{key}_median_us"], e[f"{key}_p95_us"]
        print(f"  {name:<20} median {med:7.2f} us   p95 {p95:7.2f} us   ({e[n]:.0f} samples)")
    print(
        f"  speed-up (median) {e['speedup_median']:.1f}x   max |state diff| {e['max_state_diff']:.2e}"
        f"   max |P diff| {e['max_cov_diff']:.2e}"
    )
    r = replay_throughput()
    print(
        f"replay, 10 min at 100 Hz through the CLI path: {r['samples']:.0f} samples in {r['wall_s']:.2f} s"
        f" = {r['samples_per_s']:,.0f} samples/s"
    )
    out = {**e, **{f"replay_{k}": v for k, v in r.items()}}
    if crossval:
        wall = crossval_time()
        print(f"cross-validation (10 folds, {os.cpu_count()} workers): {wall:.1f} s wall")
        out["crossval_wall_s"] = wall
    return out

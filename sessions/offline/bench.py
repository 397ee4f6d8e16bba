"""``gaitscope bench``: speed of the phase EKF, of replay, of the estimator stack and of cross-validation,
measured in one run; every comparison is against a baseline measured in the same run.

1. Per-sample cost (predict + update through the Python interface, ``time.perf_counter_ns`` around each
   sample) of :class:`~estimators.phase_ekf.PhaseEKF` against the baseline
   :class:`~estimators.reference.ReferencePhaseEKF` (filterpy's ``ExtendedKalmanFilter`` with the same
   model in vectorised numpy), on the same simulated trial with the shipped model; both filters run in
   lock step and the largest state and covariance difference over every sample is reported.
2. Replay throughput of a 10-minute 100 Hz trial through the command-line path (CSV in, CSV out),
   beyond start-up (after a first replay has loaded the compiled code): the streaming path
   (:meth:`GaitStatePipeline.step` per sample) against the batch path (:meth:`GaitStatePipeline.run`,
   the default), best of a few runs each; and the batch path's parts (reading, estimating, writing)
   timed one by one.
3. Per-sample cost of the whole default estimator stack (:mod:`sessions.stack`, every registered
   estimator, as a live session runs it) against the seed-000 pipeline's :meth:`GaitStatePipeline.step`.
4. Wall time of the full leave-one-subject-out cross-validation.

Targets: issue #2, gaitscope >= 20x faster than the reference and < 10 us per sample, states agree to
1e-9, cross-validation under 5 minutes on 2 cores; issue #7, replay >= 200,000 samples/s.
"""

from __future__ import annotations

import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np

from estimators.phase_ekf import PhaseEKF
from estimators.pipeline import GaitStatePipeline, PipelineConfig
from estimators.reference import ReferencePhaseEKF
from sessions import schema
from sessions.formats.models import default_model_path, load_model
from sessions.formats.replay_io import read_replay_csv, write_replay_output
from sessions.offline.replay import measurements, replay_file, run
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


def replay_throughput(minutes: float = 10.0, repeats: int = 3) -> dict[str, float]:
    """Samples per second of ``gaitscope replay`` on a ``minutes`` long 100 Hz trial, streaming and batch."""
    sensors, leg, mass = sensor_trial(minutes_schedule(minutes), rate_hz=100.0)
    sensors = sensors[sensors["time_s"] < sensors["time_s"].iloc[0] + minutes * 60]
    model, _ = load_model(default_model_path())
    config = PipelineConfig(leg_length=leg, body_mass_kg=mass)
    clock = time.perf_counter
    out: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as d:
        src, dst = Path(d) / "trial.csv", Path(d) / "out.csv"
        replay_columns(sensors.iloc[:200]).to_csv(src, index=False, float_format="%.6f")
        t0 = clock()
        replay_file(src, dst, model, config)  # start-up: compiled code and Arrow loaded
        out["startup_s"] = clock() - t0
        replay_columns(sensors).to_csv(src, index=False, float_format="%.6f")
        for name, batch, n in (("stream", False, 1), ("batch", True, repeats)):
            walls = []
            for _ in range(n):
                t0 = clock()
                summary = replay_file(src, dst, model, config, batch=batch)
                walls.append(clock() - t0)
            out[f"{name}_wall_s"] = min(walls)
            out[f"{name}_samples_per_s"] = summary.samples / min(walls)
        out["samples"] = float(summary.samples)
        parts: dict[str, list[float]] = {"read_s": [], "estimate_s": [], "write_s": []}
        for _ in range(repeats):
            t0 = clock()
            data = read_replay_csv(src)
            t1 = clock()
            columns, _ = run(data, model, config)
            t2 = clock()
            write_replay_output(dst, columns)
            t3 = clock()
            for key, wall in zip(parts, (t1 - t0, t2 - t1, t3 - t2), strict=True):
                parts[key].append(wall)
        out.update({k: min(v) for k, v in parts.items()})
    out["speedup"] = out["batch_samples_per_s"] / out["stream_samples_per_s"]
    return out


def stack_cost(samples: int = 6000) -> tuple[dict[str, float], tuple[str, ...]]:
    """Per-sample cost of the default estimator stack and of the seed-000 pipeline alone on the same
    trial; and the stack's estimators."""
    from sessions.registry import StackContext, build_stack

    model, _ = load_model(default_model_path())
    sensors, leg, mass = sensor_trial()
    data = replay_input(sensors)
    n = min(samples, data.time_s.size)
    names = [schema.REPLAY_TIME, *data.signals, schema.REPLAY_HEEL_STRIKE]
    rows = sensors[names].iloc[:n].to_dict("records")
    stack = build_stack(
        StackContext(model, leg, mass, 0.01),
        names=None,
        channels=[*data.signals, schema.REPLAY_HEEL_STRIKE],
        primary="phase_ekf",
        torque_gain=1.0,
        max_torque=40.0,
    )
    pipe = GaitStatePipeline(model, PipelineConfig(leg_length=leg, body_mass_kg=mass))
    z = np.column_stack([data.signals[k] for k in data.signals])
    hs = np.asarray(data.heel_strike)
    t_stack = np.empty(n, dtype=np.int64)
    t_pipe = np.empty(n, dtype=np.int64)
    clock = time.perf_counter_ns
    for k, row in enumerate(rows):
        t = float(row.pop(schema.REPLAY_TIME))
        channels = {str(c): float(v) for c, v in row.items()}
        t0 = clock()
        stack.step(t, channels)
        t1 = clock()
        pipe.step(t, z[k], bool(hs[k]))
        t_stack[k], t_pipe[k] = t1 - t0, clock() - t1
    s50, s95 = _percentiles(t_stack)
    p50, p95 = _percentiles(t_pipe)
    numbers = {
        "samples": float(n),
        "stack_median_us": s50,
        "stack_p95_us": s95,
        "pipeline_median_us": p50,
        "pipeline_p95_us": p95,
    }
    return numbers, stack.names


def crossval_time() -> float:
    from sessions.offline.crossval import crossvalidate

    t0 = time.perf_counter()
    crossvalidate()
    return time.perf_counter() - t0


def run_bench(crossval: bool = True, reference_samples: int = 3000) -> dict[str, float]:
    """Measure and print everything; returns the numbers."""
    cpu = platform.processor() or platform.machine()
    load = " / ".join(f"{v:.2f}" for v in os.getloadavg())
    print(f"machine: {cpu}, {os.cpu_count()} cores, Python {platform.python_version()}; load average {load}")
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
        f"replay, 10 min at 100 Hz ({r['samples']:.0f} samples) through the CLI path, beyond start-up"
        f" (first replay in the process: {r['startup_s']:.2f} s), best of 3:"
    )
    print(
        f"  streaming (step per sample)    {r['stream_samples_per_s']:>9,.0f} samples/s   ({r['stream_wall_s']:.2f} s)"
    )
    print(
        f"  batch (run, compiled loop)     {r['batch_samples_per_s']:>9,.0f} samples/s   ({r['batch_wall_s']:.2f} s)"
        f"   {r['speedup']:.1f}x"
    )
    print(
        f"  batch path apart: read CSV {1e3 * r['read_s']:.0f} ms, estimate {1e3 * r['estimate_s']:.0f} ms,"
        f" write CSV {1e3 * r['write_s']:.0f} ms (the replay writes each part while estimating the next)"
    )
    s, names = stack_cost()
    print(f"default estimator stack per sample ({', '.join(names)}), {s['samples']:.0f} samples of the default trial:")
    print(f"  EstimatorStack.step         median {s['stack_median_us']:7.2f} us   p95 {s['stack_p95_us']:7.2f} us")
    print(
        f"  GaitStatePipeline.step      median {s['pipeline_median_us']:7.2f} us   p95 {s['pipeline_p95_us']:7.2f} us"
        f"   (stack / pipeline {s['stack_median_us'] / s['pipeline_median_us']:.1f}x)"
    )
    out = {**e, **{f"replay_{k}": v for k, v in r.items()}}
    out.update({f"stack_{k}": v for k, v in s.items()})
    if crossval:
        wall = crossval_time()
        print(f"cross-validation (10 folds, {os.cpu_count()} workers): {wall:.1f} s wall")
        out["crossval_wall_s"] = wall
    load = " / ".join(f"{v:.2f}" for v in os.getloadavg())
    print(f"load average at the end: {load}")
    return out

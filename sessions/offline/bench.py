"""``gaitscope bench``: speed of the phase EKF, of replay, of the estimator stack and of cross-validation,
measured in one run; every comparison is against a baseline measured in the same run.

1. Per-sample cost (predict + update through the Python interface, ``time.perf_counter_ns`` around each
   sample) of :class:`~gaitscope.estimators.phase_ekf.PhaseEKF` against the baseline
   :class:`~gaitscope.estimators.reference.ReferencePhaseEKF` (filterpy's ``ExtendedKalmanFilter`` with the same
   model in vectorised numpy), on the same simulated trial with the shipped model; both filters run in
   lock step and the largest state and covariance difference over every sample is reported.
2. Replay throughput of a 10-minute 100 Hz trial through the command-line path (CSV in, CSV out),
   beyond start-up (after a first replay has loaded the compiled code): the estimator stack stepped per
   sample (:func:`gaitscope.sessions.offline.replay.replay_stack`), with the lock supervisor (as live) and
   without it (seed 000's filter as published), once each: the baselines; then the stack's compiled fast
   paths, supervised (:mod:`gaitscope.estimators._lock_batch`, the default) and as published
   (:meth:`GaitStatePipeline.run`, ``--as-published``), in alternation, best of a few runs each, each
   against its stepped baseline; and the as-published batch path's parts (reading, estimating, writing)
   timed one by one.
3. Per-sample cost of every registered estimator (:data:`gaitscope.sessions.registry.ESTIMATORS`, the opt-in ones
   too), each on its own through the stack interface (``step(t, z)``, ``time.perf_counter_ns`` around
   each sample, fed the channels the default stack feeds it), against its library baseline where it has
   a natural one (:data:`gaitscope.sessions.offline.baselines.BASELINES`; none for the TBE and the heel-strike
   detector), each timed in a pass of its own; a baseline of the same step is also compared with the
   estimator output by output.
4. Per-sample cost of the whole default estimator stack (:mod:`gaitscope.sessions.stack`, every registered
   estimator, as a live session runs it) against the seed-000 pipeline's :meth:`GaitStatePipeline.step`.
5. Per-sample cost of the speed-change intent estimator (:mod:`gaitscope.sessions.offline.intent_bench`) on a simulated
   walk, between events and at events, against seed 001 on filterpy's ``KalmanFilter`` (row 3 feeds it the
   default trial, which lacks its channels, so it sees no events there).
6. A GP-EKF retraining (seed 003) against the walking time it has and against GPy's documented sparse GP
   regression (:mod:`gaitscope.sessions.offline.gp_bench`).
7. Wall time of the full leave-one-subject-out cross-validation.

Targets: issue #2, gaitscope >= 20x faster than the reference and < 10 us per sample, states agree to
1e-9, cross-validation under 5 minutes on 2 cores; issue #7, replay >= 200,000 samples/s; issue #9, the intent
estimator's bookkeeping between events <= 2 us per sample.
"""

from __future__ import annotations

import math
import os
import platform
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

from gaitscope.estimators.phase_ekf import PhaseEKF
from gaitscope.estimators.pipeline import GaitStatePipeline, PipelineConfig, TrainedModel
from gaitscope.estimators.protocol import HEEL_STRIKE, Estimator, input_names
from gaitscope.estimators.reference import ReferencePhaseEKF
from gaitscope.sessions import schema
from gaitscope.sessions.formats.models import default_model_path, load_model
from gaitscope.sessions.formats.replay_io import read_replay_csv, write_replay_output
from gaitscope.sessions.offline.baselines import BASELINES, Stepper
from gaitscope.sessions.offline.gp_bench import retrain_cost
from gaitscope.sessions.offline.intent_bench import intent_cost
from gaitscope.sessions.offline.replay import measurements, replay_file, run
from gaitscope.sessions.offline.timing import step_times
from gaitscope.sessions.registry import ESTIMATORS, OPT_IN, StackContext, build_stack
from gaitscope.sessions.synth.trials import minutes_schedule, replay_columns, replay_input, sensor_trial


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
    n_ref = max(0, min(reference_samples, len(z)))
    t_fast = np.empty(len(z), dtype=np.int64)
    t_ref = np.empty(max(n_ref, 1), dtype=np.int64)
    xs, Ps = np.empty((n_ref, 4)), np.empty((n_ref, 4, 4))
    clock = time.perf_counter_ns
    # Each filter in a pass of its own (run in alternation, each slows the other through the caches);
    # ours keeps its states for the comparison, which is done outside the timed sections.
    for k in range(len(z)):
        t0 = clock()
        fast.predict(dts[k])
        fast.update(z[k])
        t_fast[k] = clock() - t0
        if k < n_ref:
            xs[k], Ps[k] = fast.x, fast.P
    dx = dp = 0.0
    t_ref[0] = 0
    for k in range(n_ref):
        t0 = clock()
        ref.predict(dts[k])
        ref.update(z[k])
        t_ref[k] = clock() - t0
        diff = np.abs(xs[k] - ref.x)
        diff[0] = min(diff[0], 1 - diff[0])
        dx = max(dx, float(diff.max()))
        dp = max(dp, float(np.abs(Ps[k] - ref.P).max()))
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
        runs = (
            ("stream", False, False, 1),
            ("supervised_stepped", False, True, 1),
            ("supervised", True, True, repeats),  # the default
            ("batch", True, False, repeats),
        )
        walls: dict[str, list[float]] = {name: [] for name, *_ in runs}
        for r in range(repeats):  # the compiled paths in alternation: each sees the load the other does
            for name, batch, supervised, n in runs:
                if r < n:
                    t0 = clock()
                    summary = replay_file(src, dst, model, config, batch=batch, supervised=supervised)
                    walls[name].append(clock() - t0)
        for name, best in ((name, min(w)) for name, w in walls.items()):
            out[f"{name}_wall_s"] = best
            out[f"{name}_samples_per_s"] = summary.samples / best
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
    out["supervised_speedup"] = out["supervised_samples_per_s"] / out["supervised_stepped_samples_per_s"]
    return out


def estimator_costs(samples: int = 6000, reference_samples: int = 3000) -> dict[str, dict[str, float]]:
    """Per-sample cost of every registered estimator's ``step(t, z)`` on the first ``samples`` samples of
    the default trial, each estimator on its own, fed every channel the simulated device sends (the six
    sensors, the true heel strikes, both legs, raw IMUs, feet, centre of mass) as a stack feeds it; and of
    its library baseline, where it has one, on the first ``reference_samples`` of them.

    Each is timed in a pass of its own: run in lock step, filterpy's work between two samples of a
    compiled estimator (hundreds of numpy calls) doubled the estimator's median. A baseline of the same
    step is then compared with the estimator, output by output, in an untimed pass.

    Returns:
        Per estimator, in the registry's order: ``samples``, ``median_us``, ``p95_us``; with a baseline
        (and ``reference_samples`` > 0) also ``ref_samples``, ``ref_median_us``, ``ref_p95_us`` and
        ``ratio`` (baseline median / the estimator's); with a baseline of the same step also
        ``max_output_diff``, ``max_state_diff`` and ``max_cov_diff``, the largest differences over the
        baseline's samples.
    """
    model, _ = load_model(default_model_path())
    sensors, leg, mass = sensor_trial()
    data = replay_input(sensors)
    n = min(samples, data.time_s.size)
    n_ref = min(reference_samples, n)
    ctx = _context(model, sensors, leg, mass)
    # every channel the simulated device sends (raw IMUs, both legs, feet, centre of mass): each
    # estimator is timed on what it reads, not on the missing-input path
    sent = {c: sensors[c].to_numpy().astype(np.float64) for c in sensors.columns if c in schema.CHANNELS}
    source = {**sent, **data.signals, HEEL_STRIKE: (sensors[HEEL_STRIKE].to_numpy() > 0.5).astype(np.float64)}
    missing = np.full(data.time_s.size, np.nan)
    t = data.time_s[:n].tolist()
    out: dict[str, dict[str, float]] = {}
    for name, make in ESTIMATORS.items():
        est = make(ctx)
        z = np.column_stack([source.get(c, missing)[:n] for c in input_names(est)])
        med, p95 = _timed(est.step, t, z)
        row = out[name] = {"samples": float(n), "median_us": med, "p95_us": p95}
        base = BASELINES.get(name)
        if base is None or n_ref == 0:
            continue
        z_ref = z if base.inputs is None else np.ascontiguousarray(base.inputs(data)[:n])
        r50, r95 = _timed(base.make(ctx).step, t[:n_ref], z_ref)
        row.update(ref_samples=float(n_ref), ref_median_us=r50, ref_p95_us=r95, ratio=r50 / med)
        if base.same_step:
            row.update(_agreement(make(ctx), base.make(ctx), t[:n_ref], z))
    return out


#: The trial's thigh channels, which the fingerprint filters read.
THIGH_CHANNELS = ("thigh_angle_deg", "thigh_vel_dps")


def _context(model: TrainedModel, sensors: pd.DataFrame, leg: float, mass: float) -> StackContext:
    """The bench's stack context: the trial's subject with the fingerprint least squares gives their walk
    (ground-truth phase and stride length), so that every registered estimator runs, ``fp_ls`` included."""
    fmap = model.fingerprints
    g = None
    if fmap is not None:
        g = tuple(
            fmap.ls_fingerprint(
                sensors["gt_phase"].to_numpy(),
                sensors["gt_stride_length_m"].to_numpy(),
                sensors["thigh_angle_deg"].to_numpy(),
            ).tolist()
        )
    return StackContext(model, leg, mass, 0.01, fingerprint=g)


def _timed(step: Callable[[float, np.ndarray], object], t: list[float], z: np.ndarray) -> tuple[float, float]:
    """Median and p95 (us) of ``step(t[k], z[k])``, sample by sample, with nothing else between them."""
    return _percentiles(step_times(step, t, z))


def _agreement(est: Estimator, ref: Stepper, t: list[float], z: np.ndarray) -> dict[str, float]:
    """Largest differences of outputs, state and covariance between ``est`` and its baseline ``ref``, fresh,
    over samples ``t`` (both fed ``z``)."""
    dy = dx = dp = 0.0
    for k, tk in enumerate(t):
        y, y_ref = est.step(tk, z[k]), ref.step(tk, z[k])
        dy = max(dy, float(np.abs(y - y_ref).max()))
        dx = max(dx, float(np.abs(np.asarray(est.state) - ref.x).max()))
        dp = max(dp, float(np.abs(np.asarray(est.covariance) - ref.P).max()))
    return {"max_output_diff": dy, "max_state_diff": dx, "max_cov_diff": dp}


def calibration_cost(walk_s: float = 60.0) -> dict[str, float]:
    """Seconds to fit a subject's fingerprint from the samples of a ``walk_s`` walk (the subject page's
    "Fit": strides cut at heel strikes, belt-speed stride length; reading the samples from a recording
    comes on top), and to refit the map from the cohort's level walking."""
    from gaitscope.estimators.fingerprint import fit_map
    from gaitscope.sessions.offline.fingerprints import training_walks
    from gaitscope.sessions.personalization.calibration import CalibrationWalk, calibrate
    from gaitscope.sessions.synth.cohort import CohortSpec

    model, _ = load_model(default_model_path())
    assert model.fingerprints is not None
    sensors, _, _ = sensor_trial([(1.0, 0.0, int(walk_s))], rate_hz=100.0)
    sensors = sensors[sensors[schema.REPLAY_TIME] <= walk_s]
    walk = CalibrationWalk(
        t=sensors[schema.REPLAY_TIME].to_numpy(np.float64),
        thigh_deg=sensors["thigh_angle_deg"].to_numpy(np.float64),
        heel_strike=sensors[HEEL_STRIKE].to_numpy() > 0.5,
        belt_m_s=sensors["gt_speed_m_s"].to_numpy(np.float64),
        stride_estimate_m=np.full(len(sensors), np.nan),
    )
    best = math.inf
    for _ in range(5):
        t0 = time.perf_counter()
        cal = calibrate(model.fingerprints, walk)
        best = min(best, time.perf_counter() - t0)
    _, walks = training_walks(CohortSpec())
    t0 = time.perf_counter()
    fit_map(walks)
    return {
        "walk_s": float(walk.t[-1] - walk.t[0]),
        "strides": float(cal.strides_used),
        "fit_s": best,
        "map_s": time.perf_counter() - t0,
    }


def stack_cost(samples: int = 6000) -> tuple[dict[str, float], tuple[str, ...]]:
    """Per-sample cost of the default estimator stack and of the seed-000 pipeline alone on the same
    trial; and the stack's estimators."""
    model, _ = load_model(default_model_path())
    sensors, leg, mass = sensor_trial()
    data = replay_input(sensors)
    n = min(samples, data.time_s.size)
    names = [schema.REPLAY_TIME, *data.signals, *THIGH_CHANNELS, schema.REPLAY_HEEL_STRIKE]
    rows = sensors[names].iloc[:n].to_dict("records")
    stack = build_stack(
        _context(model, sensors, leg, mass),
        names=None,
        channels=[*data.signals, *THIGH_CHANNELS, schema.REPLAY_HEEL_STRIKE],
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
    times = [float(row.pop(schema.REPLAY_TIME)) for row in rows]
    inputs = [{str(c): float(v) for c, v in row.items()} for row in rows]
    for k in range(n):  # each in a pass of its own: in alternation each slows the other through the caches
        t0 = clock()
        stack.step(times[k], inputs[k])
        t_stack[k] = clock() - t0
    for k in range(n):
        t0 = clock()
        pipe.step(times[k], z[k], bool(hs[k]))
        t_pipe[k] = clock() - t0
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
    from gaitscope.sessions.offline.crossval import crossvalidate

    t0 = time.perf_counter()
    crossvalidate()
    return time.perf_counter() - t0


def _print_estimators(rows: dict[str, dict[str, float]]) -> None:
    """One line per estimator: its median and p95, its baseline's median and the ratio, or none."""
    n = max(row["samples"] for row in rows.values())
    n_ref = max((row["ref_samples"] for row in rows.values() if "ref_samples" in row), default=0.0)
    print(
        f"each estimator alone, step(t, z) through the stack interface, {n:.0f} samples of the default trial"
        f" (baselines on the first {n_ref:.0f}):"
    )
    print(f"  {'estimator':<22}{'median':>10}{'p95':>11}   {'baseline':<27}{'median':>10}   ratio")
    for name, row in rows.items():
        label = f"{name} (opt-in)" if name in OPT_IN else name
        line = f"  {label:<22}{row['median_us']:7.2f} us {row['p95_us']:7.2f} us   "
        base = BASELINES.get(name)
        if base is None:
            print(f"{line}{'none':<27}{'':>10}   no reference")
            continue
        if "ref_median_us" not in row:
            print(f"{line}{base.label:<27}{'':>10}   not run (--reference-samples 0)")
            continue
        print(f"{line}{base.label:<27}{row['ref_median_us']:7.2f} us   {row['ratio']:.1f}x")
        if base.same_step:
            print(
                f"  {'':<22}max |output diff| {row['max_output_diff']:.2e}   max |state diff|"
                f" {row['max_state_diff']:.2e}   max |P diff| {row['max_cov_diff']:.2e}"
            )
    if any(not b.same_step for name, b in BASELINES.items() if name in rows):
        print(
            "  (filter only: predict + update on measurements high-passed beforehand; phase_ekf's step also"
            " high-passes, detects and runs the backup filter, so its ratio understates the filter's speed-up)"
        )


def run_bench(
    crossval: bool = True,
    reference_samples: int = 3000,
    samples: int = 6000,
    replay_minutes: float = 10.0,
    gp_retrain: bool = True,
) -> dict[str, float]:
    """Measure and print everything; returns the numbers.

    Args:
        crossval: time the cross-validation too (minutes).
        reference_samples: samples the filterpy baselines run (they are the slow part of the EKF row and
            of the per-estimator rows).
        samples: samples of the default trial for the per-estimator and the whole-stack rows.
        replay_minutes: length of the replayed trial.
        gp_retrain: time a GP-EKF retraining too (about 15 s).
    """
    cpu = platform.processor() or platform.machine()
    load = " / ".join(f"{v:.2f}" for v in os.getloadavg())
    print(f"machine: {cpu}, {os.cpu_count()} cores, Python {platform.python_version()}; load average {load}")
    e = ekf_cost(reference_samples)
    print("phase EKF, per sample (predict + update), default model, 6 channels:")
    for name, key, n in (
        ("gaitscope PhaseEKF", "fast", "samples"),
        ("filterpy reference", "ref", "reference_samples"),
    ):
        if not e[n]:
            print(f"  {name:<20} not run (--reference-samples 0)")
            continue
        med, p95 = e[f"{key}_median_us"], e[f"{key}_p95_us"]
        print(f"  {name:<20} median {med:7.2f} us   p95 {p95:7.2f} us   ({e[n]:.0f} samples)")
    if e["reference_samples"]:
        print(
            f"  speed-up (median) {e['speedup_median']:.1f}x   max |state diff| {e['max_state_diff']:.2e}"
            f"   max |P diff| {e['max_cov_diff']:.2e}"
        )
    r = replay_throughput(replay_minutes)
    print(
        f"replay, {replay_minutes:g} min at 100 Hz ({r['samples']:.0f} samples) through the CLI path, beyond start-up"
        f" (first replay in the process: {r['startup_s']:.2f} s); the compiled paths best of 3, in alternation:"
    )
    for label, key, ratio in (
        ("supervised, step per sample", "supervised_stepped", ""),
        ("supervised (default, as live)", "supervised", f"   {r['supervised_speedup']:.1f}x the stepped"),
        ("stack, step per sample", "stream", ""),
        ("batch (--as-published)", "batch", f"   {r['speedup']:.1f}x the stepped"),
    ):
        print(f"  {label:<30} {r[f'{key}_samples_per_s']:>9,.0f} samples/s   ({r[f'{key}_wall_s']:.2f} s){ratio}")
    print(
        f"  batch path apart: read CSV {1e3 * r['read_s']:.0f} ms, estimate {1e3 * r['estimate_s']:.0f} ms,"
        f" write CSV {1e3 * r['write_s']:.0f} ms (the replay writes each part while estimating the next)"
    )
    per = estimator_costs(samples, reference_samples)
    _print_estimators(per)
    s, names = stack_cost(samples)
    print(f"default estimator stack per sample ({', '.join(names)}), {s['samples']:.0f} samples of the default trial:")
    print(f"  EstimatorStack.step         median {s['stack_median_us']:7.2f} us   p95 {s['stack_p95_us']:7.2f} us")
    print(
        f"  GaitStatePipeline.step      median {s['pipeline_median_us']:7.2f} us   p95 {s['pipeline_p95_us']:7.2f} us"
        f"   (stack / pipeline {s['stack_median_us'] / s['pipeline_median_us']:.1f}x)"
    )
    i = intent_cost(max(2, samples // 200))  # 30 strides of each speed at the default 6000 samples
    print(
        f"intent estimator per sample, a simulated walk (1.0 then 1.3 m/s, forces, {i['samples']:.0f} samples,"
        f" {i['events']:.0f} at events; target between events <= 2 us):"
    )
    for part, label in (("between", "between events"), ("events", "at events")):
        print(
            f"  {label:<16} IntentEstimator.step median {i[f'{part}_median_us']:7.2f} us   p95"
            f" {i[f'{part}_p95_us']:7.2f} us   filterpy KalmanFilter, same events median"
            f" {i[f'ref_{part}_median_us']:7.2f} us   ratio {i[f'{part}_ratio']:.1f}x"
        )
    print(f"  max |output diff| {i['max_output_diff']:.2e}")
    cal = calibration_cost()
    print(
        f"fingerprint calibration from a {cal['walk_s']:.0f} s walk ({cal['strides']:.0f} strides), best of 5: "
        f"{1e3 * cal['fit_s']:.1f} ms to fit its samples (target < 2 s); "
        f"the refit of the whole map from the cohort's level walking: {1e3 * cal['map_s']:.0f} ms"
    )
    g = retrain_cost() if gp_retrain else {}
    if g:
        print(
            f"GP-EKF retraining (seed 003), the first window of the protocol's walk ({g['steps']:.0f} steps,"
            f" {g['samples']:.0f} samples, {g['budget_s']:.1f} s of walking), six sparse GPs, best / median of 3:"
        )
        print(
            f"  fit_models (FITC, 25 at inputs)  {g['fit_best_s']:.2f} / {g['fit_median_s']:.2f} s   GPy's documented"
            f" SparseGPRegression {g['ref_best_s']:.2f} / {g['ref_median_s']:.2f} s   ratio {g['ratio']:.1f}x;"
            f" {100 * g['fit_median_s'] / g['budget_s']:.0f} % of the 5 steps it has"
        )
    out = {**e, **{f"replay_{k}": v for k, v in r.items()}}
    out.update({f"gp_retrain_{k}": v for k, v in g.items()})
    out.update({f"calibration_{k}": v for k, v in cal.items()})
    out.update({f"estimator_{name}_{k}": v for name, row in per.items() for k, v in row.items()})
    out.update({f"stack_{k}": v for k, v in s.items()})
    out.update({f"intent_{k}": v for k, v in i.items()})
    if crossval:
        wall = crossval_time()
        print(f"cross-validation (10 folds, {os.cpu_count()} workers): {wall:.1f} s wall")
        out["crossval_wall_s"] = wall
    load = " / ".join(f"{v:.2f}" for v in os.getloadavg())
    print(f"load average at the end: {load}")
    return out

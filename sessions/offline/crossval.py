"""Leave-one-subject-out cross-validation on the default cohort (seed 000 III-B, III-C).

Protocol, as in the authors' code (``shared/reference/estimators.md`` section 1):

- for each held-out subject, the gait model, ``Sigma_xsub`` (itself cross-validated within the
  training subjects) and the torque profile are refitted on the other subjects;
- each of the held-out subject's 27 conditions is walked as one trial of concatenated strides
  (duplicate boundary samples dropped; 150 samples per stride, so ``dt = T / 149``) through simulated
  sensors (:func:`gaitscope.sessions.synth.cohort.simulate_sensors`, seed 000's sensor noise levels), starting from the
  paper's initial state; heel strikes are the true ones (perfect heel strikes, as for the TBE);
- phase error is wrapped, ``min(|d|, 1 - |d|)``; RMSE per stride (heel strike to heel strike), and per
  subject the mean of its stride RMSEs; stride length, incline and torque likewise; the torque error
  is the profile at the estimate against the profile at the truth;
- EKF vs TBE and EKF vs no-task EKF by paired t-tests over subjects (two-sided).

One deviation: seed 000 differentiates noise-free motion-capture angles for the velocity channels;
gaitscope's simulated gyroscope gives the true angular velocity plus white noise instead.
"""

from __future__ import annotations

import csv
import io
import itertools
import math
import multiprocessing
import os
from collections.abc import Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd
from numpy.typing import NDArray
from scipy import stats

from gaitscope.estimators.basis import Array
from gaitscope.estimators.phase_ekf import EKFConfig
from gaitscope.estimators.pipeline import PipelineConfig, TrainedModel
from gaitscope.sessions import schema
from gaitscope.sessions.formats.replay_io import ReplayInput
from gaitscope.sessions.offline.replay import run
from gaitscope.sessions.offline.training import StrideData, fit_models, stride_data, subject_grams
from gaitscope.sessions.synth.cohort import CohortSpec, SensorNoise, generate_cohort, simulate_sensors
from gaitscope.sessions.synth.trials import replay_input

#: Seed 000 Table/section III-B numbers: (mean, SD).
PAPER = {
    "phase_ekf_pct": (1.6, 0.31),
    "phase_tbe_pct": (2.1, 0.1),
    "phase_notask_pct": (2.0, 0.36),
    "stride_length_m": (0.10, 0.02),
    "incline_deg": (1.5, 0.23),
    "torque_Nm": (1.2, 0.18),
}
METRICS = tuple(PAPER)
_THREAD_VARS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")


def wrapped(d: Array) -> Array:
    """Wrapped phase distance ``min(|d|, 1 - |d|)`` for phases in [0, 1)."""
    a = np.abs(d) % 1.0
    return np.minimum(a, 1.0 - a)


def stride_rmse(err: Array, heel_strike: NDArray[np.bool_]) -> Array:
    """RMSE of ``err`` within each complete stride (heel strike to the next heel strike)."""
    hs = np.flatnonzero(heel_strike)
    return np.array([np.sqrt(np.mean(err[a:b] ** 2)) for a, b in itertools.pairwise(hs)])


@dataclass(frozen=True)
class SubjectResult:
    subject: str
    metrics: dict[str, float]
    strides: int
    #: each stride's phase RMSE (%) by estimator (``phase_ekf_pct``, ``phase_tbe_pct``, ``phase_notask_pct``),
    #: for the stride-wise tests seed 000 reported
    stride_phase: dict[str, tuple[float, ...]] = field(default_factory=dict)


@dataclass(frozen=True)
class HeldOutTrial:
    """One condition of a held-out subject through simulated sensors (:func:`subject_trials`)."""

    trial: ReplayInput
    heel_strike: NDArray[np.bool_]
    phase: Array
    stride_length_m: Array
    incline_deg: Array


def subject_trials(
    cohort: pd.DataFrame, data: StrideData, subject: str, noise: SensorNoise, seed: int
) -> tuple[float, float, Iterator[HeldOutTrial]]:
    """The subject's leg length, mass and, lazily, each of its conditions as the protocol walks them: one
    trial of concatenated strides through simulated sensors, each condition with its own noise stream
    from ``(seed, subject)``, with the ground truth."""
    rows = cohort[cohort[schema.SUBJECT] == subject]
    s = data.subjects.index(subject)
    leg = float(data.leg_length[data.subject == s][0])
    mass = float(data.mass[data.subject == s][0])

    def trials() -> Iterator[HeldOutTrial]:
        ss = np.random.SeedSequence([seed, s])
        for (_, walk), child in zip(
            rows.groupby(schema.TASK_ID, sort=True), ss.spawn(rows[schema.TASK_ID].nunique()), strict=True
        ):
            sensors = simulate_sensors(walk.sort_values(schema.TIME_S), noise, np.random.default_rng(child))
            trial = replay_input(sensors)
            assert trial.heel_strike is not None
            yield HeldOutTrial(
                trial,
                np.asarray(trial.heel_strike, dtype=bool),
                sensors["gt_phase"].to_numpy(),
                sensors["gt_stride_length_m"].to_numpy(),
                sensors["gt_incline_deg"].to_numpy(),
            )

    return leg, mass, trials()


def evaluate_subject(
    cohort: pd.DataFrame, data: StrideData, model: TrainedModel, subject: str, noise: SensorNoise, seed: int
) -> SubjectResult:
    """Run EKF, no-task EKF and TBE over every condition of one (held-out) subject."""
    leg, mass, trials = subject_trials(cohort, data, subject, noise, seed)
    base = PipelineConfig(leg_length=leg, body_mass_kg=mass, max_torque=200.0)
    notask = replace(base, ekf=EKFConfig(no_task=True))
    per: dict[str, list[Array]] = {k: [] for k in METRICS}
    for h in trials:
        hs, gt_p, gt_l, gt_r = h.heel_strike, h.phase, h.stride_length_m, h.incline_deg
        out, _ = run(h.trial, model, base)
        out_nt, _ = run(h.trial, model, notask)
        tau_true = model.torque.torque(gt_p, gt_l / leg, gt_r, mass, 200.0)
        per["phase_ekf_pct"].append(100 * stride_rmse(wrapped(out["phase"] - gt_p), hs))
        per["phase_tbe_pct"].append(100 * stride_rmse(wrapped(out["tbe_phase"] - gt_p), hs))
        per["phase_notask_pct"].append(100 * stride_rmse(wrapped(out_nt["phase"] - gt_p), hs))
        per["stride_length_m"].append(stride_rmse(out["stride_length_m"] - gt_l, hs))
        per["incline_deg"].append(stride_rmse(out["incline_deg"] - gt_r, hs))
        per["torque_Nm"].append(stride_rmse(out["torque_Nm"] - tau_true, hs))
    metrics = {k: float(np.mean(np.concatenate(v))) for k, v in per.items()}
    phases = ("phase_ekf_pct", "phase_tbe_pct", "phase_notask_pct")
    stride_phase = {k: tuple(float(x) for x in np.concatenate(per[k])) for k in phases}
    return SubjectResult(str(subject), metrics, int(sum(len(v) for v in per["phase_ekf_pct"])), stride_phase)


def _fold(args: tuple[CohortSpec, int, SensorNoise, int]) -> SubjectResult:
    spec, k, noise, seed = args
    cohort = generate_cohort(spec)
    data = stride_data(cohort)
    grams = subject_grams(data, 20, 20)
    train = [s for s in range(len(data.subjects)) if s != k]
    model = fit_models(data, train, grams=grams)
    return evaluate_subject(cohort, data, model, data.subjects[k], noise, seed)


def crossvalidate(
    spec: CohortSpec | None = None,
    noise: SensorNoise | None = None,
    seed: int = 0,
    workers: int | None = None,
) -> list[SubjectResult]:
    """Leave-one-subject-out over the cohort; one process per fold, ``workers`` at a time."""
    spec = spec or CohortSpec()
    noise = noise or SensorNoise()
    workers = workers or min(os.cpu_count() or 1, spec.n_subjects)
    jobs = [(spec, k, noise, seed) for k in range(spec.n_subjects)]
    if workers == 1:
        return [_fold(j) for j in jobs]
    # Fresh interpreters, one BLAS thread each: forked workers inherit a BLAS thread pool that then
    # fights over the cores (measured: 6x slower on 2 cores).
    for var in _THREAD_VARS:
        os.environ.setdefault(var, "1")
    with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        return list(pool.map(_fold, jobs))


@dataclass(frozen=True)
class Summary:
    """Mean and SD over subjects of every metric, and the paired t-tests of the phase RMSEs."""

    mean_sd: dict[str, tuple[float, float]]
    p_ekf_vs_tbe: float
    p_ekf_vs_notask: float
    #: the same tests over strides (every held-out stride a pair), as seed 000 reported them: far more pairs,
    #: so smaller p for the same effect; the tests over subjects above are the conservative ones
    p_ekf_vs_tbe_strides: float = math.nan
    p_ekf_vs_notask_strides: float = math.nan


def summary(results: Sequence[SubjectResult]) -> Summary:
    """Mean, SD and paired t-test p-values (EKF vs TBE, EKF vs no-task) over subjects, and over strides."""
    table = {k: np.array([r.metrics[k] for r in results]) for k in METRICS}
    ekf = table["phase_ekf_pct"]

    def strides(k: str) -> np.ndarray:
        return np.concatenate([np.asarray(r.stride_phase.get(k, ()), dtype=float) for r in results])

    ekf_s, tbe_s, nt_s = strides("phase_ekf_pct"), strides("phase_tbe_pct"), strides("phase_notask_pct")
    by_stride = ekf_s.size > 1 and ekf_s.size == tbe_s.size == nt_s.size
    return Summary(
        mean_sd={k: (float(v.mean()), float(v.std(ddof=1))) for k, v in table.items()},
        p_ekf_vs_tbe=float(stats.ttest_rel(ekf, table["phase_tbe_pct"]).pvalue),
        p_ekf_vs_notask=float(stats.ttest_rel(ekf, table["phase_notask_pct"]).pvalue),
        p_ekf_vs_tbe_strides=float(stats.ttest_rel(ekf_s, tbe_s).pvalue) if by_stride else math.nan,
        p_ekf_vs_notask_strides=float(stats.ttest_rel(ekf_s, nt_s).pvalue) if by_stride else math.nan,
    )


_LABELS = {
    "phase_ekf_pct": "phase RMSE, EKF (%)",
    "phase_tbe_pct": "phase RMSE, TBE (%)",
    "phase_notask_pct": "phase RMSE, no-task EKF (%)",
    "stride_length_m": "stride length RMSE (m)",
    "incline_deg": "incline RMSE (deg)",
    "torque_Nm": "torque RMSE (N m)",
}


def to_csv(results: Sequence[SubjectResult]) -> str:
    """Per-subject rows, then mean and SD rows."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["subject", "strides", *METRICS])
    for r in results:
        w.writerow([r.subject, r.strides, *(f"{r.metrics[k]:.4f}" for k in METRICS)])
    s = summary(results)
    w.writerow(["mean", "", *(f"{s.mean_sd[k][0]:.4f}" for k in METRICS)])
    w.writerow(["sd", "", *(f"{s.mean_sd[k][1]:.4f}" for k in METRICS)])
    w.writerow(["paper_mean", "", *(f"{PAPER[k][0]}" for k in METRICS)])
    w.writerow(["paper_sd", "", *(f"{PAPER[k][1]}" for k in METRICS)])
    return buf.getvalue()


def _p(p: float) -> str:
    """A p-value as the tables print it; one below the smallest double (5,400 pairs) as ``< 1e-300``."""
    return "< 1e-300" if p == 0.0 else f"{p:.2g}"


def to_markdown(results: Sequence[SubjectResult]) -> str:
    """Summary against the paper, then per-subject rows."""
    s = summary(results)
    lines = [
        "| quantity | gaitscope (mean +/- SD) | seed 000 (mean +/- SD) | ratio |",
        "|---|---|---|---|",
    ]
    for k in METRICS:
        m, sd = s.mean_sd[k]
        pm, psd = PAPER[k]
        lines.append(f"| {_LABELS[k]} | {m:.3g} +/- {sd:.2g} | {pm} +/- {psd} | {m / pm:.2f} |")
    lines.append(f"| p, EKF vs TBE (paired t over subjects) | {s.p_ekf_vs_tbe:.2g} | < 0.001 | |")
    lines.append(f"| p, EKF vs no-task (paired t over subjects) | {s.p_ekf_vs_notask:.2g} | < 0.001 | |")
    lines.append(f"| p, EKF vs TBE (paired t over strides, as the paper) | {_p(s.p_ekf_vs_tbe_strides)} | < 0.001 | |")
    lines.append(
        f"| p, EKF vs no-task (paired t over strides, as the paper) | {_p(s.p_ekf_vs_notask_strides)} | < 0.001 | |"
    )
    lines += ["", "| subject | strides | " + " | ".join(_LABELS[k] for k in METRICS) + " |"]
    lines.append("|---|---|" + "---|" * len(METRICS))
    for r in results:
        lines.append(f"| {r.subject} | {r.strides} | " + " | ".join(f"{r.metrics[k]:.3g}" for k in METRICS) + " |")
    return "\n".join(lines) + "\n"

"""Gait fingerprints for seed 000's phase EKF: seed 004's personalization applied to the Kronecker model.

Seed 004 (Montes Pérez et al., ``shared/reference/estimators.md`` section 2) personalizes a thigh-angle
model; :mod:`gaitscope.estimators.fingerprint` implements it. Here the same construction personalizes seed 000's
gait model (foot angle, shank angle, heel forward and heel up over phase, normalised stride length and
incline; :mod:`gaitscope.estimators.gait_model`), and the leave-one-subject-out study on the cohort measures what
it does for the phase EKF. For each held-out subject:

- average model: seed 000's model fitted on the other subjects (:func:`~sessions.offline.training.fit_models`);
- per-subject models of the training subjects: each one's data alone, the same constrained least squares
  (:func:`~estimators.gait_model.fit_outputs` on its :func:`~sessions.offline.training.subject_grams` Gram);
- RMSE space stacked over the four outputs: a coefficient change ``d`` has the squared length
  ``mean_o (d_o^T G d_o / s_o^2)`` with ``G`` the regressor's Gram per sample over every training sample
  (seed 004 eq. 19) and ``s_o`` output o's scale, so lengths are RMS changes of the predictions over the
  training samples and the four outputs, in units of ``s_o``. Choice: ``s_o`` is the square root of the
  phase-averaged ``Sigma_R`` of the average model (sensor variance plus ``Sigma_xsub``; heel channels
  from m to leg lengths with the training subjects' mean leg length): the noise the EKF weighs each
  output's innovation by, so the components are ranked by what the filter can tell apart. Scaling by
  the sensor SDs alone (1 deg foot, 1 cm heel forward) would let foot angle and heel forward dominate
  although the filter trusts them far less than that (their ``Sigma_R`` SDs are about 4.4 deg and 3.6 cm);
- PCA about the average model: the differences ``xi_q - xi_avg`` of the training subjects' fits, second
  moment, components kept until the cumulative share first exceeds 99 % (seed 004), and
  ``P_map = U_k^T G^(-1/2)``, so ``g_i = 1`` is a change of one unit RMS. Choice: seed 004's average
  is the mean of the per-subject fits; seed 000's pooled fit is not (subjects differ in how many samples
  they have at each stride length), so the second moment is taken about the pooled fit that the
  filter runs: exactly seed 004's covariance when the two coincide (``base_offset`` records how far
  apart they are). Computed in the subjects' kernel ``K = D G D^T`` (``n x n``) rather than with
  ``G^(1/2)``: the same ``P_map``, without the Gram's square roots. Its rows are combinations of the
  subjects' differences, so every personalized model keeps seed 000's constraints;
- calibration: a level walk at 1.0 m/s of its own random stream (:func:`calibration_walk`), through the
  same simulated sensors, heel positions high-passed as the pipeline does, with the ground-truth phase,
  stride length and incline (seed 004's LS-GF was fed the ground truth). The first ``D`` seconds give
  ``g`` by least squares weighted by ``1 / s_o`` (LS-GF); its last :data:`CHECK_SECONDS` are never used
  for calibration and measure how well each model fits the subject's walking. At incline 0 the
  regressor's incline factor ``[r, 1 - r]`` is ``[0, 1]``: a level walk sees only the level half of a
  model, and the map carries a person's incline behaviour only as far as it goes with their level
  walking among the training subjects;
- subject alone: the held-out subject's own constrained fit on all its cohort conditions (an oracle:
  it sees the test conditions' kinematics);
- every variant runs with the average model's noise model ``Sigma_R``: it describes the average
  model's error on a new person, so it overstates the personalized models' error and those filters
  trust their models less than they could. Conservative and the same for every variant; a personalized
  ``Sigma_R`` would need each training subject calibrated against a map built without it;
- filters run and are scored as :func:`gaitscope.sessions.offline.crossval.evaluate_subject` runs the EKF: the
  same trials, sensor-noise draws, initial state, true heel strikes and per-stride scoring, so the
  average model's row is crossval's EKF result; paired two-sided t-tests over subjects against it.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field, replace
from typing import Final

import numpy as np
import pandas as pd
from scipy import stats

from gaitscope.estimators.basis import Array, regressor
from gaitscope.estimators.gait_model import (
    N_OUTPUTS,
    Z_FOOT_ANGLE,
    Z_HEEL_FORWARD,
    Z_HEEL_UP,
    Z_SHANK_ANGLE,
    Gram,
    evaluate,
    fit_outputs,
)
from gaitscope.estimators.pipeline import PipelineConfig, TrainedModel
from gaitscope.sessions import schema
from gaitscope.sessions.offline.crossval import stride_rmse, subject_trials, wrapped
from gaitscope.sessions.offline.replay import measurements, run
from gaitscope.sessions.offline.training import SAMPLES_PER_STRIDE, StrideData, fit_models, stride_data, subject_grams
from gaitscope.sessions.synth.cohort import (
    CohortSpec,
    SensorNoise,
    SubjectParams,
    generate_cohort,
    generate_walk,
    make_subjects,
    simulate_sensors,
)
from gaitscope.sessions.synth.trials import replay_input

__all__ = [
    "AVERAGE",
    "CALIBRATION_SECONDS",
    "CHECK_SECONDS",
    "SUBJECT",
    "CalibrationWalk",
    "EKFFingerprintStudy",
    "Errors",
    "FoldResult",
    "GaitFingerprintMap",
    "calibration_walk",
    "evaluate_fold",
    "fit_map",
    "output_scale",
    "run_study",
    "score_filters",
    "to_markdown",
    "variant",
]

ORDER: Final = 20
#: Seconds of calibration walking compared (the issue's curve).
CALIBRATION_SECONDS: Final = (10.0, 30.0, 60.0, 120.0)
CALIBRATION_SPEED_M_S: Final = 1.0
#: The calibration walk's last seconds, never used to calibrate: where each model's fit is measured.
CHECK_SECONDS: Final = 30.0
#: A calibration must have samples in every tenth of the gait cycle.
PHASE_BINS: Final = 10
_LABELS: Final = ("phase RMSE (%)", "stride length RMSE (m)", "incline RMSE (deg)")
_Z_OUTPUTS: Final = (Z_FOOT_ANGLE, Z_SHANK_ANGLE, Z_HEEL_FORWARD, Z_HEEL_UP)
_THREAD_VARS: Final = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")
#: Phase (%), stride length (m) and incline (deg): RMSEs, or p-values of their tests.
Errors = tuple[float, float, float]


def _check_samples(p: Array, l: Array, r: Array, y: Array) -> tuple[Array, Array, Array, Array]:
    p, l, r = (np.asarray(a, dtype=np.float64).reshape(-1) for a in (p, l, r))
    y = np.asarray(y, dtype=np.float64)
    if not p.size == l.size == r.size == y.shape[0] or y.ndim != 2 or y.shape[1] != N_OUTPUTS:
        raise ValueError(
            f"phase, stride length, incline and outputs (n, 4) differ: {p.size}, {l.size}, {r.size}, {y.shape}"
        )
    if not (np.isfinite(p).all() and np.isfinite(l).all() and np.isfinite(r).all() and np.isfinite(y).all()):
        raise ValueError("the calibration walk has non-finite values (NaN or inf); drop those samples first")
    return p, l, r, y


@dataclass(frozen=True)
class GaitFingerprintMap:
    """Seed 004's personalization map of seed 000's gait model.

    Attributes:
        base: the average model's coefficients ``(4, 2, 2, 2N+1)``.
        p_map: ``(k, 4, 2, 2, 2N+1)``; the model of fingerprint ``g`` is ``base + g @ p_map``.
        explained: cumulative share of the second moment of the subjects' differences per component.
        scale: ``s_o`` per output (deg, deg, leg lengths, leg lengths): the unit of RMSE space.
        gram: ``G``, ``(c, c)``, the regressor's Gram per training sample.
        base_offset: RMS distance (units) from ``base`` to the mean of the per-subject fits.
    """

    base: Array
    p_map: Array
    explained: Array
    scale: Array
    gram: Array
    base_offset: float = 0.0

    @property
    def n_components(self) -> int:
        return int(self.p_map.shape[0])

    @property
    def order(self) -> int:
        return (int(self.base.shape[-1]) - 1) // 2

    def coef(self, g: Array) -> Array:
        """The model of fingerprint ``g`` ``(k,)``: coefficients like :attr:`base`."""
        return self.base + np.tensordot(np.asarray(g, dtype=np.float64), self.p_map, axes=1)

    def rms(self, delta: Array) -> float:
        """RMS change (units of :attr:`scale`) of the predictions over the training samples and outputs."""
        d = np.asarray(delta, dtype=np.float64).reshape(N_OUTPUTS, -1) / self.scale[:, None]
        return float(np.sqrt(max(np.einsum("oi,ij,oj->", d, self.gram, d) / N_OUTPUTS, 0.0)))

    def fit_rmse(self, coef: Array, p: Array, l: Array, r: Array, y: Array) -> float:
        """RMS of ``(y - model) / s_o`` over samples and outputs: how well ``coef`` fits a walk."""
        p, l, r, y = _check_samples(p, l, r, y)
        e = (y - evaluate(coef, p, l, r)) / self.scale
        return float(np.sqrt(np.mean(e**2)))

    def fingerprint(self, p: Array, l: Array, r: Array, y: Array) -> Array:
        """LS-GF: the ``g`` minimising ``sum ((y - model(g)) / s_o)^2`` over a calibration walk.

        Args:
            p, l, r: true phase, normalised stride length and incline (deg), ``(n,)``.
            y: measured foot and shank angles (deg) and high-passed heel positions (leg lengths), ``(n, 4)``.

        Raises:
            ValueError: mismatched or non-finite inputs, a walk that leaves a tenth of the gait cycle
                without samples, or one that does not determine every component.
        """
        p, l, r, y = _check_samples(p, l, r, y)
        covered = np.unique(np.floor((p % 1.0) * PHASE_BINS).astype(np.int64)).size
        if covered < PHASE_BINS:
            raise ValueError(
                f"the calibration walk is too short: {p.size} samples cover {covered} of the {PHASE_BINS} "
                "tenths of the gait cycle (walk at least one whole stride, better several)"
            )
        A = regressor(p, l, r, self.order)
        B = A @ self.p_map.reshape(self.n_components, N_OUTPUTS, -1).transpose(1, 2, 0)  # (4, n, k)
        M = (B / self.scale[:, None, None]).reshape(-1, self.n_components)
        e = ((y - evaluate(self.base, p, l, r)) / self.scale).T.reshape(-1)
        if np.linalg.matrix_rank(M) < self.n_components:
            raise ValueError("the calibration walk does not determine every fingerprint component")
        return np.asarray(np.linalg.lstsq(M, e, rcond=None)[0], dtype=np.float64)


def output_scale(model: TrainedModel, leg_length_m: float) -> Array:
    """``s_o``: square roots of the phase-averaged ``Sigma_R`` of ``model`` at the four position channels,
    heel ones converted from m to leg lengths (``leg_length_m``)."""
    var = np.diag(model.noise.mean())[list(_Z_OUTPUTS)]
    return np.sqrt(var) / np.array([1.0, 1.0, leg_length_m, leg_length_m])


def fit_map(
    grams: Sequence[Gram], base: Array, scale: Array, *, variance_threshold: float = 0.99
) -> GaitFingerprintMap:
    """The personalization map from the training subjects' Grams (module docstring).

    Args:
        grams: one :class:`~gaitscope.estimators.gait_model.Gram` per training subject (outputs in the model's units).
        base: the average model ``(4, 2, 2, 2N+1)``, fitted on the same subjects.
        scale: ``s_o`` ``(4,)`` (:func:`output_scale`).
        variance_threshold: keep components until their cumulative share exceeds it (seed 004: 99 %).

    Raises:
        ValueError: fewer than two subjects, a threshold outside (0, 1], or non-positive scales.
    """
    if len(grams) < 2:
        raise ValueError(f"a map needs at least two training subjects, got {len(grams)}")
    if not 0.0 < variance_threshold <= 1.0:
        raise ValueError(f"variance_threshold must be in (0, 1], got {variance_threshold}")
    scale = np.asarray(scale, dtype=np.float64)
    if scale.shape != (N_OUTPUTS,) or not np.all(scale > 0):
        raise ValueError(f"scale needs {N_OUTPUTS} positive entries, got {scale.tolist()}")
    order = (base.shape[-1] - 1) // 2
    fits = np.array([fit_outputs(g, order) for g in grams])  # (n, 4, 2, 2, K)
    G = sum((g.G for g in grams), np.zeros_like(grams[0].G)) / sum(g.n for g in grams)
    D = (fits - base).reshape(len(grams), N_OUTPUTS, -1) / scale[None, :, None]  # differences in units
    K = np.einsum("aoi,ij,boj->ab", D, G, D) / N_OUTPUTS  # subjects' kernel in RMSE space
    lam, W = np.linalg.eigh((K + K.T) / 2.0)
    lam, W = lam[::-1], W[:, ::-1]
    keep = lam > lam[0] * 1e-12
    lam, W = lam[keep], W[:, keep]
    explained = np.cumsum(lam) / lam.sum()
    k = min(int(np.searchsorted(explained, variance_threshold, side="right")) + 1, lam.size)
    U = np.einsum("ak,aoi->koi", W[:, :k], D) / np.sqrt(lam[:k])[:, None, None]  # unit RMS directions
    p_map = (U * scale[None, :, None]).reshape(k, *base.shape)
    fmap = GaitFingerprintMap(base=base, p_map=p_map, explained=explained, scale=scale, gram=G)
    return replace(fmap, base_offset=fmap.rms(fits.mean(axis=0) - base))


@dataclass(frozen=True)
class CalibrationWalk:
    """A calibration walk: time (s from its start), true state and measured outputs (see
    :meth:`GaitFingerprintMap.fingerprint`)."""

    t: Array
    p: Array
    l: Array
    r: Array
    y: Array

    @property
    def duration_s(self) -> float:
        return float(self.t[-1] - self.t[0]) if self.t.size else 0.0

    def window(self, start_s: float, stop_s: float) -> CalibrationWalk:
        """The samples with ``start_s <= t < stop_s``; refused if the walk ends before ``stop_s``."""
        if stop_s > self.duration_s + 1e-9:
            raise ValueError(f"the calibration walk lasts {self.duration_s:.1f} s; {stop_s:.1f} s were asked for")
        m = (self.t >= start_s) & (self.t < stop_s)
        return CalibrationWalk(self.t[m], self.p[m], self.l[m], self.r[m], self.y[m])

    def arrays(self) -> tuple[Array, Array, Array, Array]:
        return self.p, self.l, self.r, self.y


def calibration_walk(
    subject: SubjectParams, leg_length_m: float, noise: SensorNoise, rng: np.random.Generator, seconds: float
) -> CalibrationWalk:
    """At least ``seconds`` of level walking at :data:`CALIBRATION_SPEED_M_S` through simulated sensors.

    Heel positions high-passed over the whole walk as the pipeline does (:func:`sessions.offline.replay.measurements`)
    and divided by ``leg_length_m``; the state is the walk's ground truth.
    """
    strides = int(np.ceil(seconds / 0.8)) + 2  # a stride at 1 m/s lasts well over 0.8 s
    walk_rng, sensor_rng = rng.spawn(2)
    walk = generate_walk(subject, [(CALIBRATION_SPEED_M_S, 0.0, strides)], walk_rng)
    sensors = simulate_sensors(walk, noise, sensor_rng)
    z = measurements(replay_input(sensors))
    y = z[:, list(_Z_OUTPUTS)] / np.array([1.0, 1.0, leg_length_m, leg_length_m])
    t = sensors[schema.REPLAY_TIME].to_numpy(np.float64)
    out = CalibrationWalk(
        t=t - t[0],
        p=sensors["gt_phase"].to_numpy(np.float64),
        l=sensors["gt_stride_length_m"].to_numpy(np.float64) / leg_length_m,
        r=sensors["gt_incline_deg"].to_numpy(np.float64),
        y=y,
    )
    if out.duration_s < seconds:
        raise ValueError(f"{strides} strides lasted {out.duration_s:.1f} s, less than {seconds} s")
    return out


AVERAGE: Final = "average"
SUBJECT: Final = "subject"
#: Entropy of the calibration walk's stream: ``(seed, subject index, _CAL_STREAM)`` (crossval's trials use
#: ``(seed, subject index)``).
_CAL_STREAM: Final = 4


def variant(seconds: float) -> str:
    """Name of the model personalized from ``seconds`` of calibration walking."""
    return f"cal_{seconds:g}s"


@dataclass(frozen=True)
class FoldResult:
    """One held-out subject.

    Attributes:
        subject: its code.
        strides: strides scored per variant.
        rmse: variant -> (phase %, stride length m, incline deg), each the mean of the stride RMSEs.
        calibration_fit: variant -> fit RMSE (units of ``scale``) on the calibration walk's last
            :data:`CHECK_SECONDS`.
        cohort_fit: variant -> fit RMSE on the subject's cohort strides (every test condition, clean).
        g: personalized variant -> its fingerprint.
        explained: the fold map's cumulative shares; ``n_components`` of them kept.
        scale: ``s_o`` of the fold (deg, deg, leg lengths, leg lengths).
        base_offset: RMS distance from the pooled average model to the mean of the per-subject fits.
    """

    subject: str
    strides: int
    rmse: dict[str, Errors]
    calibration_fit: dict[str, float]
    cohort_fit: dict[str, float]
    g: dict[str, tuple[float, ...]]
    explained: tuple[float, ...]
    n_components: int
    scale: tuple[float, ...]
    base_offset: float


def _subject_outputs(data: StrideData, s: int) -> tuple[Array, Array, Array, Array]:
    """One subject's cohort samples as the model sees them (as :func:`subject_grams` builds them)."""
    P, L, R, Z, _ = data.rows(s)
    leg = np.repeat(data.leg_length[data.subject == s], SAMPLES_PER_STRIDE)
    return P, L, R, np.stack([Z[:, 0], Z[:, 2], Z[:, 4] / leg, Z[:, 5] / leg], axis=1)


def score_filters(
    cohort: pd.DataFrame,
    data: StrideData,
    models: dict[str, TrainedModel],
    subject: str,
    noise: SensorNoise,
    seed: int,
) -> tuple[dict[str, Errors], int]:
    """The EKF of each model over every condition of ``subject``: trials, noise draws, configuration and
    scoring of :func:`gaitscope.sessions.offline.crossval.evaluate_subject`. Returns per-model (phase %, stride
    length m, incline deg) RMSE and the number of strides scored."""
    leg, mass, trials = subject_trials(cohort, data, subject, noise, seed)
    config = PipelineConfig(leg_length=leg, body_mass_kg=mass, max_torque=200.0)
    per: dict[str, list[list[Array]]] = {name: [[], [], []] for name in models}
    for h in trials:
        hs = h.heel_strike
        for name, model in models.items():
            out, _ = run(h.trial, model, config)
            per[name][0].append(100 * stride_rmse(wrapped(out["phase"] - h.phase), hs))
            per[name][1].append(stride_rmse(out["stride_length_m"] - h.stride_length_m, hs))
            per[name][2].append(stride_rmse(out["incline_deg"] - h.incline_deg, hs))
    strides = int(sum(len(v) for v in next(iter(per.values()))[0]))
    return {name: _triple([float(np.mean(np.concatenate(v))) for v in m]) for name, m in per.items()}, strides


def _triple(values: Sequence[float]) -> Errors:
    a, b, c = values
    return a, b, c


def evaluate_fold(
    spec: CohortSpec, k: int, noise: SensorNoise, seed: int, seconds: Sequence[float] = CALIBRATION_SECONDS
) -> FoldResult:
    """Hold out subject ``k`` of the cohort of ``spec``: map, calibrations, filters (module docstring)."""
    if not seconds or min(seconds) <= 0:
        raise ValueError(f"calibration durations must be positive, got {list(seconds)}")
    cohort = generate_cohort(spec)
    data = stride_data(cohort)
    grams = subject_grams(data, ORDER, ORDER)
    train = [s for s in range(len(data.subjects)) if s != k]
    model = fit_models(data, train, grams=grams)
    leg_train = float(np.mean([data.leg_length[data.subject == s][0] for s in train]))
    fmap = fit_map([grams[0][s] for s in train], model.coef, output_scale(model, leg_train))

    leg = float(data.leg_length[data.subject == k][0])
    rng = np.random.default_rng(np.random.SeedSequence([seed, k, _CAL_STREAM]))
    walk = calibration_walk(make_subjects(spec)[k], leg, noise, rng, max(seconds) + CHECK_SECONDS)
    check = walk.window(walk.duration_s - CHECK_SECONDS, walk.duration_s)
    coefs = {AVERAGE: model.coef}
    g: dict[str, tuple[float, ...]] = {}
    for d in seconds:
        gd = fmap.fingerprint(*walk.window(0.0, d).arrays())
        g[variant(d)] = tuple(float(x) for x in gd)
        coefs[variant(d)] = fmap.coef(gd)
    coefs[SUBJECT] = fit_outputs(grams[0][k], ORDER)
    own = _subject_outputs(data, k)
    models = {name: replace(model, coef=c, fingerprints=None) for name, c in coefs.items()}
    rmse, strides = score_filters(cohort, data, models, data.subjects[k], noise, seed)
    return FoldResult(
        subject=data.subjects[k],
        strides=strides,
        rmse=rmse,
        calibration_fit={name: fmap.fit_rmse(c, *check.arrays()) for name, c in coefs.items()},
        cohort_fit={name: fmap.fit_rmse(c, *own) for name, c in coefs.items()},
        g=g,
        explained=tuple(float(x) for x in fmap.explained),
        n_components=fmap.n_components,
        scale=tuple(float(x) for x in fmap.scale),
        base_offset=fmap.base_offset,
    )


def _fold(args: tuple[CohortSpec, int, SensorNoise, int, tuple[float, ...]]) -> FoldResult:
    return evaluate_fold(*args)


@dataclass(frozen=True)
class EKFFingerprintStudy:
    """The folds, the calibration durations and paired t-tests against the average model.

    ``tests``: variant -> two-sided paired t-test p-values over subjects (phase, stride length, incline).
    """

    folds: list[FoldResult]
    seconds: tuple[float, ...]
    tests: dict[str, Errors] = field(default_factory=dict)

    @property
    def variants(self) -> tuple[str, ...]:
        return (AVERAGE, *(variant(d) for d in self.seconds), SUBJECT)

    def column(self, name: str, metric: int) -> Array:
        """One variant's metric over the folds."""
        return np.array([f.rmse[name][metric] for f in self.folds])

    def gain_share(self, name: str, metric: int) -> float:
        """``(average - variant) / (average - subject)`` of the means over folds (NaN without a gain)."""
        avg, var, own = (float(self.column(v, metric).mean()) for v in (AVERAGE, name, SUBJECT))
        return (avg - var) / (avg - own) if avg - own > 0 else float("nan")


def run_study(
    spec: CohortSpec | None = None,
    noise: SensorNoise | None = None,
    seed: int = 0,
    workers: int | None = None,
    seconds: Sequence[float] = CALIBRATION_SECONDS,
    folds: Sequence[int] | None = None,
) -> EKFFingerprintStudy:
    """Leave each subject of ``folds`` (default all) out of the cohort of ``spec`` (default the default
    cohort); one process per fold, ``workers`` at a time (1: in this process)."""
    spec = spec or CohortSpec()
    noise = noise or SensorNoise()
    ks = list(range(spec.n_subjects)) if folds is None else list(folds)
    if not ks or any(not 0 <= k < spec.n_subjects for k in ks):
        raise ValueError(f"folds must be subject indices in 0..{spec.n_subjects - 1}, got {ks}")
    jobs = [(spec, k, noise, seed, tuple(float(d) for d in seconds)) for k in ks]
    workers = workers or min(os.cpu_count() or 1, len(jobs))
    if workers == 1:
        results = [_fold(j) for j in jobs]
    else:
        # As crossval: fresh interpreters with one BLAS thread each (forked pools fight over the cores).
        for var in _THREAD_VARS:
            os.environ.setdefault(var, "1")
        with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn")) as pool:
            results = list(pool.map(_fold, jobs))
    study = EKFFingerprintStudy(results, tuple(float(d) for d in seconds))
    if len(results) >= 2:
        for name in study.variants[1:]:
            p = [float(stats.ttest_rel(study.column(name, m), study.column(AVERAGE, m)).pvalue) for m in range(3)]
            study.tests[name] = _triple(p)
    return study


def _label(name: str) -> str:
    if name == AVERAGE:
        return "average (other subjects)"
    if name == SUBJECT:
        return "subject alone (oracle)"
    return f"personalized, {name[4:-1]} s calibration"


def to_markdown(study: EKFFingerprintStudy) -> str:
    """Mean +/- SD per variant, share of the oracle's gain, t-tests, and per-subject rows."""
    f0 = study.folds[0]
    ks = sorted({f.n_components for f in study.folds})
    lines = [
        f"Leave-one-subject-out over {len(study.folds)} subjects ({f0.strides} strides each); every variant "
        "runs with the average model's noise model. Fits are RMS over samples and the four outputs in units "
        f"of the phase-averaged Sigma_R SDs (fold 1: foot {f0.scale[0]:.2f} deg, shank {f0.scale[1]:.2f} deg, "
        f"heel forward {f0.scale[2]:.4f}, heel up {f0.scale[3]:.4f} leg lengths). Components kept (99 %): "
        f"{', '.join(map(str, ks))}.",
        "",
        "| model | " + " | ".join(_LABELS) + " | fit, calibration check | fit, cohort strides |",
        "|---|---|---|---|---|---|",
    ]
    for name in study.variants:
        cells = []
        for m in range(3):
            v = study.column(name, m)
            cells.append(f"{v.mean():.3g} +/- {v.std(ddof=1) if v.size > 1 else float('nan'):.2g}")
        cal = np.mean([f.calibration_fit[name] for f in study.folds])
        own = np.mean([f.cohort_fit[name] for f in study.folds])
        lines.append(f"| {_label(name)} | " + " | ".join(cells) + f" | {cal:.3f} | {own:.3f} |")
    lines += ["", "Share of the subject-alone model's gain over the average model (from the means):", ""]
    lines += ["| model | " + " | ".join(_LABELS) + " |", "|---|---|---|---|"]
    for name in study.variants[1:-1]:
        lines.append(f"| {_label(name)} | " + " | ".join(f"{study.gain_share(name, m):.2f}" for m in range(3)) + " |")
    if study.tests:
        lines += ["", "Paired two-sided t-tests over subjects against the average model (p):", ""]
        lines += ["| model | " + " | ".join(_LABELS) + " |", "|---|---|---|---|"]
        for name, p in study.tests.items():
            lines.append(f"| {_label(name)} | " + " | ".join(f"{x:.2g}" for x in p) + " |")
    lines += ["", "Per subject: phase (%) / stride length (m) / incline (deg) RMSE", ""]
    lines.append("| subject | k | " + " | ".join(study.variants) + " |")
    lines.append("|---|---|" + "---|" * len(study.variants))
    for f in study.folds:
        row = " | ".join(" / ".join(f"{x:.3g}" for x in f.rmse[n]) for n in study.variants)
        lines.append(f"| {f.subject} | {f.n_components} | {row} |")
    lines += ["", "Per subject: fingerprints g (units) and base offset (pooled fit to mean of the subjects' fits)", ""]
    lines.append("| subject | " + " | ".join(f"g, {d:g} s" for d in study.seconds) + " | base offset |")
    lines.append("|---|" + "---|" * (len(study.seconds) + 1))
    for f in study.folds:
        gs = " | ".join(", ".join(f"{x:.2f}" for x in f.g[variant(d)]) for d in study.seconds)
        lines.append(f"| {f.subject} | {gs} | {f.base_offset:.3f} |")
    return "\n".join(lines) + "\n"

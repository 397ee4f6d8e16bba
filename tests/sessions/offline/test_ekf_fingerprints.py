"""Fingerprints of seed 000's gait model on a small cohort: the map's unit, calibration, refusals, the study."""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import pandas as pd
import pytest
from scipy import stats

from gaitscope.estimators.basis import Array
from gaitscope.estimators.gait_model import N_OUTPUTS, evaluate, fit_outputs, gait_constraints
from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.sessions.offline.crossval import evaluate_subject
from gaitscope.sessions.offline.ekf_fingerprints import (
    AVERAGE,
    CHECK_SECONDS,
    SUBJECT,
    CalibrationWalk,
    EKFFingerprintStudy,
    GaitFingerprintMap,
    calibration_walk,
    fit_map,
    output_scale,
    run_study,
    to_markdown,
    variant,
)
from gaitscope.sessions.offline.training import SAMPLES_PER_STRIDE, StrideData, fit_models, stride_data, subject_grams
from gaitscope.sessions.synth.cohort import CohortSpec, SensorNoise, generate_cohort, make_subjects

SPEC = CohortSpec(n_subjects=4, strides_per_condition=4, inclines_deg=(-5.0, 0.0, 5.0))
HELD_OUT = 1  # VC02: far enough from the others' average for personalization to matter
SECONDS = (10.0, 30.0, 60.0, 120.0)


@dataclass
class Fold:
    cohort: pd.DataFrame
    data: StrideData
    train: list[int]
    model: TrainedModel
    fmap: GaitFingerprintMap
    walk: CalibrationWalk


@pytest.fixture(scope="module")
def fold() -> Fold:
    cohort = generate_cohort(SPEC)
    data = stride_data(cohort)
    grams = subject_grams(data, 20, 20)
    train = [s for s in range(SPEC.n_subjects) if s != HELD_OUT]
    model = fit_models(data, train, grams=grams)
    leg_train = float(np.mean([data.leg_length[data.subject == s][0] for s in train]))
    fmap = fit_map([grams[0][s] for s in train], model.coef, output_scale(model, leg_train))
    leg = float(data.leg_length[data.subject == HELD_OUT][0])
    rng = np.random.default_rng(np.random.SeedSequence([0, HELD_OUT, 4]))
    walk = calibration_walk(make_subjects(SPEC)[HELD_OUT], leg, SensorNoise(), rng, max(SECONDS) + CHECK_SECONDS)
    return Fold(cohort, data, train, model, fmap, walk)


def _training_outputs(data: StrideData, subjects: list[int]) -> tuple[Array, Array, Array, Array]:
    parts = []
    for s in subjects:
        P, L, R, Z, _ = data.rows(s)
        leg = np.repeat(data.leg_length[data.subject == s], SAMPLES_PER_STRIDE)
        parts.append((P, L, R, np.stack([Z[:, 0], Z[:, 2], Z[:, 4] / leg, Z[:, 5] / leg], axis=1)))
    P, L, R, Y = (np.concatenate([p[i] for p in parts]) for i in range(4))
    return P, L, R, Y


def test_a_unit_fingerprint_is_one_unit_rms_over_the_training_data(fold: Fold) -> None:
    fmap = fold.fmap
    P, L, R, _ = _training_outputs(fold.data, fold.train)
    assert 1 <= fmap.n_components <= len(fold.train)
    changes = []
    for i in range(fmap.n_components):
        change = evaluate(fmap.p_map[i], P, L, R) / fmap.scale  # (n, 4) in units of each output's scale
        assert np.sqrt(np.mean(change**2)) == pytest.approx(1.0, rel=1e-6)
        assert fmap.rms(fmap.p_map[i]) == pytest.approx(1.0, rel=1e-6)
        changes.append(change.reshape(-1))
    # the components are orthogonal in RMSE space
    C = np.array(changes) @ np.array(changes).T / changes[0].size
    np.testing.assert_allclose(C, np.eye(fmap.n_components), atol=1e-6)
    # k is the first count whose cumulative share exceeds 99 %
    e = fmap.explained
    assert np.all(np.diff(e) >= 0) and e[-1] == pytest.approx(1.0)
    assert e[fmap.n_components - 1] > 0.99 and (fmap.n_components == 1 or e[fmap.n_components - 2] <= 0.99)


def test_the_map_is_the_pca_of_the_subjects_differences_in_rmse_space(fold: Fold) -> None:
    fmap = fold.fmap
    grams = subject_grams(fold.data, 20, 20)[0]
    D = np.array([(fit_outputs(grams[s], 20) - fmap.base).reshape(N_OUTPUTS, -1) for s in fold.train])
    lam, O = np.linalg.eigh(fmap.gram)
    root = (O * np.sqrt(lam)) @ O.T
    X = np.concatenate([D[:, o] @ root / fmap.scale[o] for o in range(N_OUTPUTS)], axis=1) / 2.0  # / sqrt(4)
    psi, U = np.linalg.eigh(X.T @ X)
    psi, U = psi[::-1], U[:, ::-1]
    np.testing.assert_allclose(fmap.explained, (np.cumsum(psi) / psi.sum())[: fmap.explained.size], atol=1e-8)
    for i in range(fmap.n_components):  # P_map = U_k^T G^(-1/2), up to each direction's sign
        u = (
            np.concatenate([fmap.p_map[i].reshape(N_OUTPUTS, -1)[o] @ root / fmap.scale[o] for o in range(N_OUTPUTS)])
            / 2.0
        )
        assert abs(float(u @ U[:, i])) == pytest.approx(1.0, abs=1e-6)


def test_personalized_models_keep_seed_000s_constraints(fold: Fold) -> None:
    g = np.random.default_rng(0).normal(scale=3.0, size=fold.fmap.n_components)
    coef = fold.fmap.coef(g)
    for o in range(N_OUTPUTS):
        C, d = gait_constraints(20, o)
        np.testing.assert_allclose(C @ coef[o].reshape(-1), d, atol=1e-8)


def test_personalization_fits_the_held_out_subjects_walk_better_than_the_average(fold: Fold) -> None:
    fmap, walk = fold.fmap, fold.walk
    cal = walk.window(0.0, 120.0)
    check = walk.window(walk.duration_s - CHECK_SECONDS, walk.duration_s)
    coef = fmap.coef(fmap.fingerprint(*cal.arrays()))
    assert fmap.fit_rmse(coef, *cal.arrays()) < 0.9 * fmap.fit_rmse(fmap.base, *cal.arrays())
    assert fmap.fit_rmse(coef, *check.arrays()) < 0.9 * fmap.fit_rmse(fmap.base, *check.arrays())
    # g = 0 is the average model, and g is the least-squares optimum: any nudge fits worse
    g = fmap.fingerprint(*cal.arrays())
    for i in range(fmap.n_components):
        nudged = g + 0.05 * np.eye(fmap.n_components)[i]
        assert fmap.fit_rmse(fmap.coef(nudged), *cal.arrays()) > fmap.fit_rmse(coef, *cal.arrays())


def test_more_calibration_seconds_do_not_make_the_fit_worse(fold: Fold) -> None:
    fmap, walk = fold.fmap, fold.walk
    check = walk.window(walk.duration_s - CHECK_SECONDS, walk.duration_s)
    cal = walk.window(0.0, max(SECONDS))
    on_check, on_cal = [], []
    for d in SECONDS:
        coef = fmap.coef(fmap.fingerprint(*walk.window(0.0, d).arrays()))
        on_check.append(fmap.fit_rmse(coef, *check.arrays()))
        on_cal.append(fmap.fit_rmse(coef, *cal.arrays()))
    assert on_cal[-1] == min(on_cal)  # the longest calibration is the optimum over its own samples
    # on walking no calibration saw: never more than 0.5 % worse than with fewer seconds
    assert all(b <= a * 1.005 for a, b in itertools.pairwise(on_check))
    assert on_check[-1] <= on_check[0]


def test_a_short_or_non_finite_calibration_walk_is_refused(fold: Fold) -> None:
    fmap, walk = fold.fmap, fold.walk
    with pytest.raises(ValueError, match=r"too short: .* cover [0-9] of the 10 tenths of the gait cycle"):
        fmap.fingerprint(*walk.window(0.0, 0.5).arrays())
    p, l, r, y = walk.window(0.0, 10.0).arrays()
    y = y.copy()
    y[5, 2] = np.nan
    with pytest.raises(ValueError, match="non-finite values"):
        fmap.fingerprint(p, l, r, y)
    with pytest.raises(ValueError, match="differ"):
        fmap.fingerprint(p[:-1], l, r, y)
    with pytest.raises(ValueError, match=r"the calibration walk lasts .* s; 1000.0 s were asked for"):
        walk.window(0.0, 1000.0)


def test_the_study_scores_every_model_and_its_average_row_is_crossvals_ekf(fold: Fold) -> None:
    study = run_study(SPEC, workers=1, seconds=(10.0, 30.0), folds=(0, HELD_OUT))
    assert [f.subject for f in study.folds] == ["VC01", "VC02"]
    assert study.variants == (AVERAGE, variant(10.0), variant(30.0), SUBJECT)
    for f in study.folds:
        assert f.strides == 9 * 4  # 3 speeds x 3 inclines x 4 strides, heel strike to heel strike
        assert set(f.rmse) == set(study.variants)
        assert all(np.isfinite(v) and v > 0 for r in f.rmse.values() for v in r)
        assert f.calibration_fit[SUBJECT] < f.calibration_fit[AVERAGE]  # on a walk the oracle never saw
    assert set(study.tests) == set(study.variants[1:])
    # the average model's filter is crossval's EKF: same trials, noise, configuration, scoring
    ref = evaluate_subject(fold.cohort, fold.data, fold.model, "VC02", SensorNoise(), 0)
    got = study.folds[1].rmse[AVERAGE]
    assert got[0] == pytest.approx(ref.metrics["phase_ekf_pct"], rel=1e-12)
    assert got[1] == pytest.approx(ref.metrics["stride_length_m"], rel=1e-12)
    assert got[2] == pytest.approx(ref.metrics["incline_deg"], rel=1e-12)
    md = to_markdown(study)
    assert "| personalized, 10 s calibration |" in md and "| subject alone (oracle) |" in md
    assert md.count("\n| VC0") == 4  # per-subject errors and fingerprints


#: The headline check's cohort: all ten subjects (each fold's map from the other nine), three inclines and
#: four strides per condition; five folds took 5 min on the shared 2-core development machine.
HEADLINE_SPEC = CohortSpec(strides_per_condition=4, inclines_deg=(-5.0, 0.0, 5.0))


@pytest.fixture(scope="module")
def headline() -> EKFFingerprintStudy:
    return run_study(HEADLINE_SPEC, workers=1, seconds=(10.0,), folds=range(5))


@pytest.mark.slow
def test_a_10_s_calibration_lowers_every_held_out_subjects_incline_error(headline: EKFFingerprintStudy) -> None:
    """The study's headline on held-out filters (docs/results.md: incline RMSE lower for 8 of 10 subjects,
    p = 0.012): personalized from 10 s of walking, the phase EKF's incline RMSE over every condition is
    below the average model's for each of the five held-out subjects, a one-sided sign test of
    0.5^5 = 0.031 (five subjects are too few for the t-test over subjects at 0.05; phase is not
    significant in the full study and stride length only just, p = 0.048). The thinnest margin is VC01's
    (2.628 against 2.638 deg); with the two models swapped the check fails on every subject."""
    personal, average = headline.column(variant(10.0), 2), headline.column(AVERAGE, 2)
    assert np.all(personal < average)
    assert stats.binomtest(int(np.sum(personal < average)), len(personal), alternative="greater").pvalue < 0.05


def test_folds_must_be_subjects_of_the_cohort() -> None:
    with pytest.raises(ValueError, match=r"folds must be subject indices in 0\.\.3"):
        run_study(SPEC, workers=1, folds=(4,))

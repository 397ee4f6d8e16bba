"""Training data preparation and model fitting from a LocoHub table."""

import numpy as np
import pandas as pd
import pytest

from gaitscope.sessions import schema
from gaitscope.sessions.offline.training import SAMPLES_PER_STRIDE, StrideData, fit_models, stride_data


def test_strides_are_arranged_with_their_task(small_data: StrideData) -> None:
    assert small_data.z.shape == (3 * 27 * 3, SAMPLES_PER_STRIDE, 6)
    assert small_data.speeds == (0.8, 1.0, 1.2) and len(small_data.inclines) == 9
    # stride length = speed x stride time, normalised by leg length (~1.1-1.7 leg lengths when walking)
    assert 1.0 < small_data.l.min() and small_data.l.max() < 1.8
    assert np.all(small_data.moment.max(axis=1) > 0.5)  # plantarflexor push-off, N m/kg
    heel = small_data.z[..., 4:6]
    assert np.abs(heel.mean(axis=(0, 1))).max() < 0.05  # high-passed: no 0.9 m offset left


def test_a_short_stride_is_refused(small_cohort: pd.DataFrame) -> None:
    frame = small_cohort.drop(index=small_cohort.index[5])
    with pytest.raises(ValueError, match="has 149 samples; phase-indexed tables have 150 per stride"):
        stride_data(frame)


def test_subject_metadata_needs_size_and_mass(small_cohort: pd.DataFrame) -> None:
    frame = small_cohort.assign(**{schema.SUBJECT_METADATA: "height_m:1.7"})
    with pytest.raises(ValueError, match="has no mass_kg"):
        stride_data(frame)
    frame = small_cohort.assign(**{schema.SUBJECT_METADATA: "mass_kg:70"})
    with pytest.raises(ValueError, match="neither leg_length_m nor height_m"):
        stride_data(frame)


def test_noise_model_needs_two_training_subjects(small_data: StrideData) -> None:
    with pytest.raises(ValueError, match="at least two subjects"):
        fit_models(small_data, [0])


def test_fitted_model_reproduces_its_training_data(small_data: StrideData, small_model) -> None:
    from gaitscope.estimators.gait_model import evaluate

    s = small_data.subject == 0
    P = np.broadcast_to(small_data.p, (int(s.sum()), SAMPLES_PER_STRIDE)).reshape(-1)
    L = np.repeat(small_data.l[s], SAMPLES_PER_STRIDE)
    R = np.repeat(small_data.r[s], SAMPLES_PER_STRIDE)
    foot = evaluate(small_model.coef, P, L, R)[:, 0]
    rms = np.sqrt(np.mean((foot - small_data.z[s][..., 0].reshape(-1)) ** 2))
    assert rms < 6.0  # deg: the population model fits a training subject to a few degrees


def test_a_table_without_heel_positions_trains_a_model_that_ignores_them(small_cohort: pd.DataFrame) -> None:
    from gaitscope.estimators.pipeline import GaitStatePipeline

    data = stride_data(small_cohort.drop(columns=list(schema.OPTIONAL_TRAINING_COLUMNS)))
    assert data.outputs == (True, True, False, False)
    model = fit_models(data)
    assert model.outputs == (True, True, False, False)
    pipe = GaitStatePipeline(model)
    pipe.step(0.0, np.array([10.0, -50.0, 15.0, -20.0, 0.2, 0.05]), heel_strike=False)
    pipe.step(0.01, np.array([9.5, -50.0, 14.8, -20.0, 0.2, 0.05]), heel_strike=False)
    assert np.all(np.isfinite(pipe.ekf.y[:4])) and np.all(np.isnan(pipe.ekf.y[4:]))  # heel channels unused


def test_time_indexed_tables_are_resampled_to_the_phase_grid() -> None:
    from gaitscope.sessions.synth.cohort import CohortSpec, generate_cohort, resample_walk

    phase_table = generate_cohort(CohortSpec(n_subjects=2, strides_per_condition=3, inclines_deg=(0.0, 5.0)))
    groups = phase_table.groupby([schema.SUBJECT, schema.TASK_ID], sort=False)
    time_table = pd.concat([resample_walk(g, 100.0) for _, g in groups], ignore_index=True)
    a = stride_data(phase_table)
    b = stride_data(time_table.drop(columns=[schema.PHASE_IPSI]))  # LocoHub's time-indexed layout
    assert b.z.shape == a.z.shape
    np.testing.assert_allclose(b.pdot, a.pdot, rtol=0.01)  # stride durations from the heel strikes
    np.testing.assert_allclose(b.l, a.l, rtol=0.01)
    foot_rms = np.sqrt(np.mean((b.z[..., 0] - a.z[..., 0]) ** 2))
    assert foot_rms < 1.0  # deg: 100 Hz samples interpolated onto 150 phases


def test_short_steps_are_refused(small_cohort: pd.DataFrame) -> None:
    few = small_cohort.groupby([schema.SUBJECT, schema.TASK_INFO, schema.STEP]).head(5)
    with pytest.raises(ValueError, match=r"has 5 samples \(10 needed\)"):
        stride_data(few.drop(columns=[schema.PHASE_IPSI]))

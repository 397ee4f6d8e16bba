"""Seed 004's study on a small cohort: the protocol runs, scores after the first strides, and reports it."""

from __future__ import annotations

import numpy as np

from gaitscope.sessions.offline.fingerprints import (
    SAMPLES_PER_STRIDE,
    SCHEDULE,
    SKIP_STRIDES,
    STRIDES_PER_BLOCK,
    held_out_walk,
    run_study,
    to_markdown,
)
from gaitscope.sessions.synth.cohort import CohortSpec, make_subjects

SPEC = CohortSpec(n_subjects=4, strides_per_condition=6)


def test_the_test_walk_follows_the_schedule_at_150_samples_per_stride() -> None:
    walk = held_out_walk(make_subjects(SPEC)[0], SPEC.seed)
    assert walk.t.size == len(SCHEDULE) * STRIDES_PER_BLOCK * SAMPLES_PER_STRIDE
    assert np.all(np.diff(walk.t) > 0)
    dt = np.diff(walk.t)[:10]
    assert np.allclose(dt, 1.0 / (SAMPLES_PER_STRIDE * walk.phase_rate[:10]), rtol=1e-6)
    # the velocity is the angle's derivative
    assert np.allclose(np.gradient(walk.thigh_deg, walk.t), walk.thigh_vel_dps)


def test_the_study_scores_every_filter_and_personalisation_fits_better() -> None:
    study = run_study(SPEC)
    assert [f.code for f in study.folds] == ["VC01", "VC02", "VC03", "VC04"]
    for f in study.folds:
        assert set(f.rmse) == {"gf", "avg", "ls"}
        assert f.ls_fit_rmse_deg < f.avg_fit_rmse_deg
        assert len(f.g_ls) == f.n_components
        assert all(np.isfinite(v) for r in f.rmse.values() for v in r)
    md = to_markdown(study)
    assert "Table III" in md and "Table II" in md and "Table I" in md and "p = " in md
    assert SKIP_STRIDES < STRIDES_PER_BLOCK * len(SCHEDULE)

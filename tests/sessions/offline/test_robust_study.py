"""The phase EKF on real-walking effects: the study runs and reports every subset and condition."""

from __future__ import annotations

import math

from gaitscope.sessions.offline.robust_study import ESTIMATORS, SUBSETS, WALKING, run_study, to_markdown
from gaitscope.sessions.synth.cohort import CohortSpec
from gaitscope.sessions.synth.real_walks import RealWalkSpec


def test_the_study_reports_every_subset_estimator_and_condition() -> None:
    study = run_study(RealWalkSpec(bouts=1), CohortSpec(n_subjects=1))
    for subset in SUBSETS:
        for name in ESTIMATORS:
            for c in WALKING:
                assert 0 <= study.rmse_pct[(subset, name, c)] <= 50 or math.isnan(study.rmse_pct[(subset, name, c)])
            assert study.stalls[(subset, name)] >= 0
        assert study.standing_rate[subset] >= 0
    # with every sensor the EKF tracks steady walking far better than with the shank alone
    assert study.rmse_pct[("foot + shank + heel", "EKF", "steady")] < study.rmse_pct[("shank only", "EKF", "steady")]
    md = to_markdown(study)
    assert "| shank only | EKF |" in md and "phase rate standing" in md

"""Seed 003's findings on the cohort: the study runs, the GP-EKF learns, and the stop freezes its phase."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from gaitscope.estimators.gp import FitOptions
from gaitscope.sessions.offline.gp_study import run_study, to_markdown, write_figure
from gaitscope.sessions.synth.cohort import CohortSpec
from gaitscope.sessions.synth.speed_walks import SpeedProtocol


def test_the_gp_ekf_learns_beats_the_time_based_phase_and_freezes_at_a_stop(tmp_path: Path) -> None:
    protocol = SpeedProtocol(walk_s=30.0, standing_s=6.0)
    study = run_study(protocol, CohortSpec(n_subjects=2), options=FitOptions(max_iters=60))
    assert len(study.runs) == 2 and study.fits >= 6
    for r in study.runs:
        assert r.ekf_rmse_pct < r.time_rmse_pct  # the paper's comparison, per subject
        assert len(r.installed) >= 2  # it retrained while walking
        assert r.stopped_in_stance
        assert abs(r.ekf_stop_rate) < 0.05 and abs(r.ekf_stop_error) < 0.1  # frozen where it stopped ...
        assert r.time_stop_error > 0.2  # ... while the time-based phase ran on
        assert r.stop_torque_s < 1.0 and r.stop_torque_s <= r.published_stop_torque_s  # the hold takes it out
        assert np.isfinite(r.step_rmse[:10]).all()
    # seed 003's test is the two-sided Wilcoxon; with every subject better, exactly twice the one-sided p
    assert study.wilcoxon_p == 2 * study.wilcoxon_p_one_sided == 2 / 2 ** len(study.runs)
    md = to_markdown(study)
    assert "| VC01 |" in md and "two-sided, as the paper tested" in md and "Learning curve" in md
    written = write_figure(study, tmp_path)
    assert [p.name for p in written] == ["gp_ekf_learning.csv", "gp_ekf_learning.svg"]
    assert written[1].read_text().lstrip().startswith("<?xml")

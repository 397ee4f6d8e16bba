"""Seed 001's evaluation on the cohort's speed-change walks."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gaitscope.server.cli import main
from gaitscope.sessions.offline.intent_study import run_filter, run_study, step_data, to_markdown
from gaitscope.sessions.synth.cohort import CohortSpec, make_subjects
from gaitscope.sessions.synth.intent_walks import IntentProtocol, commanded_trial


def test_the_filter_sees_every_step_of_a_trial() -> None:
    trial = commanded_trial(make_subjects(CohortSpec())[0], 1, 0, IntentProtocol())
    log = run_filter(trial)
    strides = len(trial.stride_start_s)
    assert 2 * strides - 3 <= len(log.ms_t) <= 2 * strides  # two mid-stances a stride
    assert len(log.td_t) >= len(log.ms_t) - 1
    v0, _, step = step_data(log)
    assert len(v0) >= len(log.ms_t) - 2
    assert np.all((step > 0.4) & (step < 1.0))
    assert np.all(np.abs(log.com_error) == 0)  # the measured centre of mass was read


def test_the_study_reproduces_seed_001s_comparisons_on_a_small_cohort() -> None:
    study = run_study(spec=CohortSpec(n_subjects=3))
    cohort, paper = study.commanded["cohort"], study.commanded["paper"]
    n_trials = 3 * 6
    assert cohort.sign_steps > 200
    assert cohort.sign_rate[0] > 0.55 > paper.sign_rate[0] - 0.05  # a fitted model beats the Ekso user's
    assert cohort.on_time >= 0.8 * n_trials
    assert cohort.corr_desired > 0.5
    assert 0.005 < study.step_rmse_in_sample_m < 0.03
    assert study.step_rmse_held_out_m >= study.step_rmse_in_sample_m * 0.9
    assert study.com_rmse[0] < 0.2  # kinematic estimate: within a foot length of the truth
    for name in ("subject", "kinematic", "last_change", "step_change"):
        assert study.commanded[name].sign_steps > 0
    md = to_markdown(study)
    assert "69 % [59-78]" in md and "BKF, the cohort's kappa" in md and "baseline" in md


def test_the_command_writes_the_table(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["crossval", "--study", "intent", "--out-dir", str(tmp_path)]) == 0
    text = (tmp_path / "intent.md").read_text()
    assert "sign of next speed change correct" in text
    assert "wall time" in capsys.readouterr().out
    with pytest.raises(SystemExit):
        main(["crossval", "--study", "intent", "--step-lead", "2"])

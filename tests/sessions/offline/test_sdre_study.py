"""Seed 002's study, on a few short trials."""

from __future__ import annotations

import numpy as np

from gaitscope.sessions.offline import sdre_study
from gaitscope.sessions.synth.fes_leg import seated_trial, two_link_trial


def test_estimators_of_the_seated_study_track_a_trial_to_within_a_few_degrees() -> None:
    tr = seated_trial("P2-L", 9, duration_s=12.0)
    for jac in (False, True):
        knee = sdre_study.seated_knee(tr, (1e-6, 10.0), jac)
        assert sdre_study._rmse(knee, tr.knee_deg) < 3.0
    assert sdre_study._rmse(sdre_study.rmx_knee(tr), tr.knee_deg[::10]) < 3.0


def test_two_link_estimators_track_the_simulated_leg() -> None:
    tr = two_link_trial(3, 1.0, duration_s=5.0)
    for jac in (False, True):
        hip, knee = sdre_study.two_link_angles(tr, (1e-6, 1e-4), jac)
        assert sdre_study._rmse(hip, tr.hip_deg) < 1.0 and sdre_study._rmse(knee, tr.knee_deg) < 1.0


def test_markdown_puts_the_thesis_numbers_beside_ours() -> None:
    s = sdre_study.SeatedResult(
        ("a 1", "b 1"), np.array([1.0, 2.0]), np.array([1.5, 2.5]), np.array([2.0, np.nan]), (1, 1), (1, 1)
    )
    t = sdre_study.TwoLinkResult((0.5,), np.ones((1, 1, 2)), 2 * np.ones((1, 1, 2)), (1, 1), (1, 1), (1, 1), (2, 2))
    w = sdre_study.WalkingResult((1,), np.array([5.0]), np.array([6.0]), 20.0)
    md = sdre_study.to_markdown(sdre_study.SdreStudy(s, t, w))
    assert "| thesis (3 subjects x 2 legs x 3 trials, encoder) | 1.77 | 2.04 | 2.79 | 0.005 | 0.035 |" in md
    assert "| RMX | 2.00 | NA |" in md
    assert "| thesis | 0.20 | 0.23 | 0.60 | 0.76 |" in md

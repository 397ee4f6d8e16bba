"""Seed 002's study, on a few short trials."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from gaitscope.sessions.offline import sdre_study
from gaitscope.sessions.synth.fes_leg import LEGS, seated_trial, two_link_trial


def _small_q_grids(monkeypatch: pytest.MonkeyPatch, n2: tuple[float, float]) -> list[tuple[float, float]]:
    """Two values per ``Q`` entry (the study's grids are 7 x 7); the grid's points."""
    monkeypatch.setattr(sdre_study, "N1_GRID", (1e-6, 1e-4))
    monkeypatch.setattr(sdre_study, "N2_GRID", n2)
    return [(n1, x) for n1 in (1e-6, 1e-4) for x in n2]


def _argmin(scores: dict[Any, float]) -> Any:
    return min(scores, key=scores.__getitem__)


def test_estimators_of_the_seated_study_track_a_trial_to_within_a_few_degrees() -> None:
    tr = seated_trial("P2-L", 9, duration_s=12.0)
    for jac in (False, True):
        knee = sdre_study.seated_knee(tr, (1e-6, 10.0), jac)
        assert sdre_study._rmse(knee, tr.knee_deg) < 3.0
    assert sdre_study._rmse(sdre_study.rmx_knee(tr, 0.75), tr.knee_deg[::10]) < 3.0


def test_two_link_estimators_track_the_simulated_leg() -> None:
    tr = two_link_trial(3, 1.0, duration_s=5.0)
    for jac in (False, True):
        hip, knee = sdre_study.two_link_angles(tr, (1e-6, 1e-4), jac)
        assert sdre_study._rmse(hip, tr.hip_deg) < 1.0 and sdre_study._rmse(knee, tr.knee_deg) < 1.0


def test_every_seated_comparator_is_tuned_on_the_pretrial_and_scored_with_its_choice(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    grid = _small_q_grids(monkeypatch, (1e-3, 10.0))
    r = sdre_study.run_seated(legs=("P2-L",), trials=1, duration_s=8.0)
    pre = seated_trial("P1-L", sdre_study.PRETRIAL_SEED, duration_s=8.0)
    taus = {tau: sdre_study.rmx_pretrial_rmse(pre, tau) for tau in sdre_study.TAU_GRID}
    assert r.tau_rmx in sdre_study.TAU_GRID and r.tau_rmx == _argmin(taus)
    assert max(taus.values()) > 1.5 * min(taus.values())  # the choice matters: 0.5 s here, not the old fixed 1 s
    for q, jac in ((r.q_sdre, False), (r.q_ekf, True)):
        scores = {g: sdre_study._rmse(sdre_study.seated_knee(pre, g, jac), pre.knee_deg) for g in grid}
        assert q == _argmin(scores)
    tr = seated_trial("P2-L", sdre_study.SEED + 10 * LEGS.index("P2-L") + 1, duration_s=8.0)
    assert r.rmx[0] == sdre_study.rmx_pretrial_rmse(tr, r.tau_rmx)
    assert r.sdre[0] == sdre_study._rmse(sdre_study.seated_knee(tr, r.q_sdre, False), tr.knee_deg)
    assert r.ekf[0] == sdre_study._rmse(sdre_study.seated_knee(tr, r.q_ekf, True), tr.knee_deg)


def test_two_link_q_of_both_estimators_is_what_the_pretrial_minimises(monkeypatch: pytest.MonkeyPatch) -> None:
    grid = _small_q_grids(monkeypatch, (1e-4, 1e-2))
    r = sdre_study.run_two_link(levels=(0.5,), seeds=1, variants=False)
    pre = two_link_trial(sdre_study.PRETRIAL_SEED, 0.5)
    for q, jac in ((r.q_sdre, False), (r.q_ekf, True)):
        scores = {g: sum(sdre_study.two_link_rmse(pre, g, jac)) for g in grid}
        assert q == _argmin(scores) and len(set(scores.values())) == len(grid)
    assert r.variants == ()


def test_walking_baseline_time_constant_is_tuned_on_the_left_out_subject() -> None:
    r = sdre_study.run_walking(subjects=(1,), minutes=0.25)
    pre = sdre_study.cohort_walk(sdre_study.WALK_PRETRIAL_SUBJECT, 0.25)
    scores = {tau: sdre_study.walking_baseline_rmse(pre, tau) for tau in sdre_study.TAU_GRID}
    assert r.tau_baseline == _argmin(scores)
    assert max(scores.values()) > 1.5 * min(scores.values())
    assert r.baseline[0] == sdre_study.walking_baseline_rmse(sdre_study.cohort_walk(1, 0.25), r.tau_baseline)


def test_tuning_takes_the_first_lowest_finite_score() -> None:
    score = {0.05: math.nan, 0.1: 2.0, 0.2: 1.0, 0.3: 1.0, 0.5: math.inf}
    assert sdre_study._argmin(score.__getitem__, list(score)) == 0.2
    assert sdre_study._tune_tau(lambda tau: abs(tau - 0.7)) == 0.75


def _lag_ms(filtered: np.ndarray, raw: np.ndarray) -> int:
    """The shift (ms, at 1 kHz) by which ``filtered`` best matches ``raw`` delayed."""
    n = len(raw) - 400
    errs = [float(np.mean((filtered[k : k + n] - raw[:n]) ** 2)) for k in range(300)]
    return int(np.argmin(errs))


def test_the_causal_lowpass_lags_as_the_thesis_notes_and_starts_at_rest() -> None:
    tr = seated_trial("P2-L", 9, duration_s=14.0)
    raw = sdre_study._measurements(tr, 1, None)[:, 1]
    causal = sdre_study._measurements(tr, 1, sdre_study.LOWPASS)[:, 1]
    zero = sdre_study._measurements(tr, 1, sdre_study.ZERO_PHASE)[:, 1]
    fast = sdre_study._measurements(tr, 1, sdre_study.CAUSAL_25HZ)[:, 1]
    assert 100 <= _lag_ms(causal, raw) <= 160  # 2 / omega_c = 127 ms
    assert _lag_ms(zero, raw) <= 3 and 8 <= _lag_ms(fast, raw) <= 18
    assert sdre_study._delay_ms(sdre_study.LOWPASS) == pytest.approx(127.3, abs=0.1)
    assert np.max(np.abs(causal[:1000] - raw[0])) < 0.1  # no start-up transient (m/s^2)


def test_markdown_puts_the_thesis_numbers_and_every_tuning_beside_ours() -> None:
    v = sdre_study.SeatedVariant(sdre_study.ZERO_PHASE, np.array([1.0, 2.0]), np.array([1.0, 2.1]), (2, 2), (3, 3))
    s = sdre_study.SeatedResult(
        ("a 1", "b 1"), np.array([1.0, 2.0]), np.array([1.5, 2.5]), np.array([2.0, np.nan]), (1, 1), (1, 1), 0.3, (v,)
    )
    tv = sdre_study.TwoLinkVariant("both a = 0", (1, 1), (1, 1), (0.1, 0.2), (0.3, 0.8))
    t = sdre_study.TwoLinkResult(
        (0.5,), np.ones((1, 1, 2)), 2 * np.ones((1, 1, 2)), (1, 1), (1, 1), (1, 1), (2, 2), (tv,)
    )
    w = sdre_study.WalkingResult((1,), np.array([5.0]), np.array([6.0]), 20.0, 0.5)
    md = sdre_study.to_markdown(sdre_study.SdreStudy(s, t, w))
    assert "| thesis (3 subjects x 2 legs x 3 trials, encoder) | 1.77 | 2.04 | 2.79 | 0.005 | 0.035 |" in md
    assert "| RMX | 2.00 | NA |" in md
    assert "| thesis | 0.20 | 0.23 | 0.60 | 0.76 |" in md
    assert "RMX's complementary-filter time constant 0.3 s" in md
    assert "(tau 0.5 s, tuned on subject 0)" in md
    assert "SDRE below EKF in 2 of 2 trials; RMX below SDRE in 0 of 1 " in md
    assert f"| {sdre_study.ZERO_PHASE.label} | 0 | 1.50 | 1.55 | 1 of 2 | 1 | (2, 2) | (3, 3) | 0 of 1 | 1 |" in md
    assert "| thesis (real legs) | | 1.77 | 2.04 | 15 of 18 | 0.005 | | | 4 of 15 | 0.035 |" in md
    assert "| both a = 0 | 0.10 | 0.20 | 0.30 | 0.80 | 3.0 | 4.0 |" in md
    assert "| thesis | 0.20 | 0.23 | 0.60 | 0.76 | 3.0 | 3.3 |" in md

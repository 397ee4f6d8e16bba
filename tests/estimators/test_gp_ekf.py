"""Seed 003's GP-EKF (:mod:`estimators.gp_ekf`, :mod:`estimators.gp_ekf_estimator`) on the cohort's version of
the paper's protocol (``gaitscope.sessions.synth.speed_walks``: treadmill speed 0.4-1.2 m/s over 20 s, then a sudden
stop): the update against the paper's equations in numpy, tracking against the time-based estimate, the
stop, retraining and its check, freeze and rollback, and finite outputs on any input."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gaitscope.estimators.gp import FitOptions
from gaitscope.estimators.gp_ekf import GPEKF, GPEKFConfig, Offer
from gaitscope.estimators.gp_ekf_estimator import (
    COHORT_COLUMNS,
    ControlSurface,
    GPEKFEstimator,
    build_default,
    default_arrays,
    load_default,
)
from gaitscope.estimators.gp_models import GPModelSet, TrainingWindow, check_models, fit_models, heldout_rmse
from gaitscope.estimators.protocol import HEEL_STRIKE as HS
from gaitscope.estimators.protocol import Estimator, input_names, output_names
from gaitscope.sessions import schema as s
from gaitscope.sessions.synth.cohort import CohortSpec, generate_cohort, make_subjects
from gaitscope.sessions.synth.speed_walks import SpeedProtocol, speed_walk

#: The population the first model is fitted to: level walking at the protocol's speeds, VC01 left out.
POPULATION = CohortSpec(
    n_subjects=6, speeds_m_s=(0.4, 0.6, 0.8, 1.0, 1.2), inclines_deg=(0.0,), strides_per_condition=3
)
FIT = FitOptions(max_iters=60)
#: VC01's sudden stop after this walk falls in mid-stance (asserted below), as in seed 003 Fig. 8.
WALK = SpeedProtocol(walk_s=20.7, standing_s=10.0)
Run = tuple[dict[str, np.ndarray], list[tuple[TrainingWindow, GPModelSet, Offer]]]


@pytest.fixture(scope="module")
def default() -> tuple[GPModelSet, ControlSurface]:
    frame = generate_cohort(POPULATION)
    frame = frame[frame[s.SUBJECT] != "VC01"]
    return build_default({c: frame[c].to_numpy() for c in COHORT_COLUMNS}, FIT)


@pytest.fixture(scope="module")
def walk() -> pd.DataFrame:
    return speed_walk(make_subjects(CohortSpec())[0], WALK)


def _estimator(default: tuple[GPModelSet, ControlSurface], config: GPEKFConfig | None = None) -> GPEKFEstimator:
    return GPEKFEstimator(*default, mass_kg=make_subjects(CohortSpec())[0].mass_kg, config=config)


def _inputs(walk: pd.DataFrame, est: GPEKFEstimator) -> np.ndarray:
    return np.column_stack([walk[c].to_numpy(np.float64) for c in input_names(est)])


def _run(est: GPEKFEstimator, t: np.ndarray, Z: np.ndarray, retrain: bool = True) -> Run:
    """Step through a walk; fit each training window inline and offer it (what a session does in a worker)."""
    out = np.empty((t.size, len(est.outputs)))
    offers = []
    for k in range(t.size):
        out[k] = est.step(float(t[k]), Z[k])
        window = est.take_window() if retrain else None
        if window is not None:
            models = fit_models(window, FIT)
            offers.append((window, models, est.offer(models)))
    return dict(zip(output_names(est), out.T, strict=True)), offers


@pytest.fixture(scope="module")
def run(default: tuple[GPModelSet, ControlSurface], walk: pd.DataFrame) -> Run:
    est = _estimator(default)
    return _run(est, walk[s.TIME_S].to_numpy(), _inputs(walk, est))


def _time_based(t: np.ndarray, hs: np.ndarray, to: np.ndarray) -> np.ndarray:
    """Seed 003's baseline ``t_n / T_(n-1)`` (at most 1) from the true heel strikes and toe-offs."""
    out = np.full(t.size, np.nan)
    strikes, toes = np.flatnonzero(hs), np.flatnonzero(to)
    for a, b in zip(strikes[1:], [*strikes[2:], t.size], strict=True):
        prev = strikes[strikes < a][-1]
        T = t[toes[toes > prev][0]] - t[prev]
        out[a:b] = np.minimum((t[a:b] - t[a]) / T, 1.0)
    return out


# --- the filter's maths -------------------------------------------------------------------------------
def test_update_is_the_papers_ekf_update(default: tuple[GPModelSet, ControlSurface]) -> None:
    models = default[0]
    f = GPEKF(models)
    x0, P0 = np.array([0.42, 1.3]), np.array([[4e-4, 1e-4], [1e-4, 2e-3]])
    z = np.array([5.0, np.nan, 12.0, -40.0, 80.0, np.nan])  # knee angle and ankle velocity missing
    f.x[:], f.P[:] = x0, P0
    f.update(z)
    # seed 003 eq. 2-9 in numpy: h, H at the prior, R = M diag(GP variances) M^T (+ the velocity floor)
    p, r = x0
    mean = [g.mean(p)[0] for g in (*models.angle, *models.velocity)]
    slope = [g.derivative(p)[0] for g in (*models.angle, *models.velocity)]
    var = [g.variance_at(p)[0] for g in (*models.angle, *models.velocity)]
    h = np.array(mean[:3] + [m * r for m in mean[3:]])
    H = np.array([[d, 0.0] for d in slope[:3]] + [[r * d, m] for d, m in zip(slope[3:], mean[3:], strict=True)])
    M = np.diag([1.0, 1.0, 1.0, r, r, r])
    R = M @ np.diag(var) @ M.T + np.diag([0, 0, 0, 1, 1, 1]) * GPEKFConfig().velocity_noise_floor
    ok = np.isfinite(z)
    Hm, Rm = H[ok], R[np.ix_(ok, ok)]
    S = Hm @ P0 @ Hm.T + Rm
    K = P0 @ Hm.T @ np.linalg.inv(S)
    x = x0 + K @ (z[ok] - h[ok])
    IKH = np.eye(2) - K @ Hm
    np.testing.assert_allclose(f.x, x, rtol=1e-9)
    np.testing.assert_allclose(f.P, IKH @ P0 @ IKH.T + K @ Rm @ K.T, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(f.H, H, rtol=1e-12)
    np.testing.assert_allclose(f.S[np.ix_(ok, ok)], S, rtol=1e-9)
    assert np.isnan(f.y[~ok]).all() and np.isnan(f.K[:, ~ok]).all()
    y = z[ok] - h[ok]
    assert f.mahalanobis == pytest.approx(math.sqrt(y @ np.linalg.solve(S, y)), rel=1e-9)


def test_measurement_jacobian_matches_finite_differences(default: tuple[GPModelSet, ControlSurface]) -> None:
    models = default[0]
    f = GPEKF(models)
    for x in ([0.1, 0.9], [0.55, 1.6], [0.9, 0.4]):
        f.x[:], f.P[:] = x, 0.0
        f.update(np.full(6, np.nan))  # no update: H at the state
        f.update(np.zeros(6))  # H at the same prior (P = 0: the state does not move)
        h = 1e-6
        fd = np.stack(
            [
                (models.predict(x[0] + h, x[1])[0] - models.predict(x[0] - h, x[1])[0])[0] / (2 * h),
                (models.predict(x[0], x[1] + h)[0] - models.predict(x[0], x[1] - h)[0])[0] / (2 * h),
            ],
            axis=1,
        )
        np.testing.assert_allclose(f.H, fd, rtol=1e-5, atol=1e-4)


# --- on the protocol's walk ---------------------------------------------------------------------------
def test_tracks_stance_phase_better_than_time_based_when_speed_changes(walk: pd.DataFrame, run: Run) -> None:
    out, offers = run
    t = walk[s.TIME_S].to_numpy()
    truth = walk["gt_stance_phase"].to_numpy()
    base = _time_based(t, walk[HS].to_numpy() > 0, walk["toe_off"].to_numpy() > 0)
    speed = walk["gt_speed_m_s"].to_numpy()
    assert speed[t < 20].max() - speed[t < 20].min() > 0.7  # the sinusoid from 0.4 to 1.2 m/s
    m = (walk["condition"].to_numpy() == "walking") & np.isfinite(truth) & np.isfinite(base) & (out["in_stance"] > 0)
    ekf = math.sqrt(np.mean((out["phase"][m] - truth[m]) ** 2))
    time_based = math.sqrt(np.mean((base[m] - truth[m]) ** 2))
    assert ekf < 0.85 * time_based, (ekf, time_based)
    assert sum(o.accepted for _, _, o in offers) >= 2  # retrained on the way


def test_after_a_sudden_stop_the_phase_freezes_and_its_rate_falls_to_zero(walk: pd.DataFrame, run: Run) -> None:
    out, _ = run
    t = walk[s.TIME_S].to_numpy()
    standing = walk["condition"].to_numpy() == "standing"
    t_stop = t[standing][0]
    posture = walk["gt_stance_phase"].to_numpy()[standing][0]
    assert 0.3 < posture < 0.8  # stopped in mid-stance
    still, settled = t > t_stop + 3.0, t > t[-1] - 2.0
    assert np.all(out["in_stance"][standing] == 1.0)  # no toe-off is taken while standing
    assert np.all(out["phase_rate"][still] < 0.01)  # the velocity rows drive it to 0
    assert np.all(np.diff(out["phase"][still]) <= 1e-9)  # the phase does not progress any more ...
    assert np.ptp(out["phase"][settled]) < 0.005  # ... it is frozen ...
    assert abs(out["phase"][-1] - posture) < 0.05  # ... at the standing posture's phase
    assert np.all(out["time_phase"][t > t_stop + 1.0] == 1.0)  # while the time-based phase ran on to 1
    assert np.all(out["standing"][settled] == 1.0)
    assert np.all(out["torque_Nm"][settled] < 0.5)  # the control surface's standing value, 0 N m
    assert out["torque_Nm"][~standing].max() > 8.0  # push-off while walking (1/5 of the moment)


@pytest.mark.parametrize("phase", [0.2, 0.47, 0.75])
def test_on_the_standing_posture_the_velocity_rows_drive_the_rate_to_zero(
    default: tuple[GPModelSet, ControlSurface], phase: float
) -> None:
    models = default[0]
    posture = [g.mean(phase)[0] for g in models.angle]
    rate = {}
    for name, z in (("still", [*posture, 0.0, 0.0, 0.0]), ("angles only", [*posture, np.nan, np.nan, np.nan])):
        f = GPEKF(models)
        f.heel_strike(0.0)
        f.x[:] = (phase, 1.0)
        for _ in range(800):  # 4 s at 200 Hz
            f.predict(0.005)
            f.update(np.array(z))
        rate[name] = f.phase_rate
    assert rate["still"] < 0.01
    assert rate["angles only"] > 0.2  # the angles alone barely slow it: the paper's Q holds the rate


def test_models_are_installed_only_at_heel_strikes(walk: pd.DataFrame, run: Run) -> None:
    out, offers = run
    changed = np.flatnonzero(np.diff(out["model_version"])) + 1
    assert changed.size >= 2
    assert np.all(out["heel_strike"][changed] == 1.0)
    accepted = [m.version for _, m, o in offers if o.accepted]
    assert list(np.unique(out["model_version"]))[1:] == sorted(set(accepted))


def test_fit_models_holds_out_the_last_stance(run: Run) -> None:
    _, offers = run
    window, models, _ = offers[0]
    assert models.version == window.index == 1 and models.window is window
    assert models.span == window.span and models.steps == window.steps
    np.testing.assert_allclose(models.rmse, heldout_rmse(models, window))
    held = window.heldout
    assert held.sum() > 50 and np.all(window.step[held] == window.steps[1])
    garbage = replace(window, angle=np.where(held[:, None], window.angle + 40.0, window.angle))
    other = fit_models(garbage, FIT)  # the held-out stance never reaches the fit
    for a, b in zip((*models.angle, *models.velocity), (*other.angle, *other.velocity), strict=True):
        np.testing.assert_array_equal(a.alpha, b.alpha)
    assert np.all(other.rmse[:3] > models.rmse[:3] + 30.0)


def test_a_refit_much_worse_on_the_held_out_stance_is_refused(
    default: tuple[GPModelSet, ControlSurface], run: Run
) -> None:
    _, offers = run
    window, models, _ = next(o for o in offers if o[2].accepted)
    config = GPEKFConfig()
    assert check_models(models, default[0], config) == ""
    hip = models.angle[0]
    off = replace(models, angle=(replace(hip, offset=hip.offset + 8.0), *models.angle[1:]))  # 8 deg out
    off = replace(off, rmse=heldout_rmse(off, window))
    assert off.rmse[0] > 2.0 * models.rmse[0] + 1.0
    why = check_models(off, models, config)  # against the honest refit as the installed set
    assert why == (
        f"hip angle: held-out RMSE {off.rmse[0]:.2f} deg with version {off.version}, "
        f"{models.rmse[0]:.2f} with version {models.version}"
    )
    assert check_models(off, models, replace(config, rmse_ratio=10.0)) == ""  # within a loose tolerance


def _stop_and_resume(walk: pd.DataFrame, near_s: float, stop_s: float) -> tuple[np.ndarray, pd.DataFrame]:
    """The walk with the walker standing still for ``stop_s`` in the mid-stance after ``near_s``, then
    walking on (every later sample shifted by ``stop_s``)."""
    w = walk[walk["condition"] == "walking"].reset_index(drop=True)
    t = w[s.TIME_S].to_numpy()
    hs = np.flatnonzero(w[HS].to_numpy() > 0)
    a = hs[t[hs] > near_s][0]
    i = a + int(0.4 * (hs[hs > a][0] - a))
    dt = float(np.median(np.diff(t)))
    n = round(stop_s / dt)
    frozen = pd.concat([w.iloc[[i]]] * n, ignore_index=True)
    frozen[HS] = 0
    out = pd.concat([w.iloc[: i + 1], frozen, w.iloc[i + 1 :]], ignore_index=True)
    out[s.TIME_S] = np.concatenate([t[: i + 1], t[i] + dt * np.arange(1, n + 1), t[i + 1 :] + n * dt])
    return out[s.TIME_S].to_numpy(), out


def test_a_window_with_a_stop_in_a_stance_is_refused_and_the_old_model_kept(
    default: tuple[GPModelSet, ControlSurface], walk: pd.DataFrame
) -> None:
    t, w = _stop_and_resume(walk, near_s=7.0, stop_s=3.0)
    est = _estimator(default)
    out, offers = _run(est, t, _inputs(w, est))
    stopped = [(win, o) for win, _, o in offers if win.t[0] < 7.5 < win.t[-1]]
    assert len(stopped) == 1
    window, offer = stopped[0]
    assert not offer.accepted and "lasted" in offer.reason, offer
    before = out["model_version"][np.searchsorted(t, window.t[-1])]
    after = out["model_version"][np.searchsorted(t, window.t[-1] + 3.0)]  # heel strikes came and went
    assert after == before
    assert all(o.accepted for win, _, o in offers if win is not window)  # the clean ones were taken


def test_a_window_with_a_lost_channel_is_refused(
    default: tuple[GPModelSet, ControlSurface], walk: pd.DataFrame
) -> None:
    est = _estimator(default)
    Z = _inputs(walk, est)
    t = walk[s.TIME_S].to_numpy()
    lost = (t > 7.5) & (t < 10.0)
    Z[lost, 1] = np.nan  # the knee encoder drops out for 2.5 s
    out, offers = _run(est, t, Z)
    assert all(np.isfinite(v).all() for v in out.values())
    hit = [(win, o) for win, _, o in offers if win.t[0] < 9.0 < win.t[-1]]
    assert len(hit) == 1 and not hit[0][1].accepted
    assert hit[0][1].reason.startswith("knee angle present in"), hit[0][1]
    m = lost & (out["in_stance"] > 0)  # the filter went on with the other five channels
    truth = walk["gt_stance_phase"].to_numpy()
    assert np.sqrt(np.nanmean((out["phase"][m] - truth[m]) ** 2)) < 0.15


def test_freeze_and_rollback(default: tuple[GPModelSet, ControlSurface], walk: pd.DataFrame, run: Run) -> None:
    _, offers = run
    good = [m for _, m, o in offers if o.accepted][:2]
    est = _estimator(default)
    t, Z = walk[s.TIME_S].to_numpy(), _inputs(walk, est)
    strikes = iter(np.flatnonzero(walk[HS].to_numpy() > 0))
    k = 0

    def to_next_heel_strike() -> None:
        nonlocal k
        stop = next(strikes)
        while k <= stop:
            est.step(float(t[k]), Z[k])
            assert est.take_window() is None  # frozen: nothing to fit
            k += 1

    est.frozen = True
    for _ in range(7):  # past a window's worth of stances
        to_next_heel_strike()
    assert est.model_version == 0 and est.filter.steps >= GPEKFConfig().retrain_every
    assert est.offer(good[0]) == Offer(good[0].version, False, "the models are frozen")
    est.frozen = False
    assert est.offer(good[0]).accepted
    est.frozen = True  # accepted, then frozen: it waits
    to_next_heel_strike()
    assert est.model_version == 0 and est.filter.waiting_version == good[0].version
    est.frozen = False
    to_next_heel_strike()
    assert est.model_version == good[0].version
    assert est.offer(good[1]).accepted
    to_next_heel_strike()
    assert est.model_version == good[1].version
    assert est.offer(good[0]).reason == f"version {good[0].version} is not newer than {good[1].version}"
    assert "not kept" in est.rollback(99)
    est.frozen = True
    assert est.rollback(good[0].version) == ""  # the operator's choice goes through a freeze
    assert est.model_version == good[1].version  # ... at the next heel strike, not mid-stance
    to_next_heel_strike()
    assert est.model_version == good[0].version
    assert [e.version for e in est.installed] == [0, good[0].version, good[1].version, good[0].version]
    assert est.rollback(0) == ""
    to_next_heel_strike()
    assert est.model_version == 0
    unchecked = replace(good[1], version=42, window=None)  # what a recording says ran: no window to check on
    est.frozen = False
    assert "no training window" in est.offer(unchecked).reason
    est.frozen = True
    est.filter.install_next(unchecked)  # a review replays it: no check, through the freeze
    to_next_heel_strike()
    assert est.model_version == 42 and est.installed[-1].models is unchecked


def test_model_sets_and_defaults_round_trip_through_arrays(default: tuple[GPModelSet, ControlSurface]) -> None:
    models, surface = load_default(default_arrays(*default))
    phase, rate = np.linspace(0.0, 1.0, 9), np.full(9, 1.2)
    for a, b in zip(models.predict(phase, rate), default[0].predict(phase, rate), strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(surface.biological(phase, rate), default[1].biological(phase, rate))
    assert surface.scale == default[1].scale and models.version == 0


def test_control_surface_goes_to_the_standing_value_at_zero_phase_rate(
    default: tuple[GPModelSet, ControlSurface],
) -> None:
    surface = default[1]
    phase = np.linspace(0.0, 1.0, 41)
    walking = surface.biological(phase, 1.2)
    assert 1.0 < walking.max() < 2.0 and phase[np.argmax(walking)] > 0.6  # push-off, N m/kg
    assert np.max(np.abs(surface.biological(phase, 0.0))) < 0.05
    assert surface.torque_at(0.8, 0.0, 80.0, 30.0) < 0.8
    assert surface.torque_at(0.8, 1.2, 500.0, 30.0) == 30.0  # bounded
    assert surface.torque_at(math.nan, 1.2, 80.0, 30.0) == 0.0


def test_heel_strikes_are_detected_from_the_foot_when_not_given(
    default: tuple[GPModelSet, ControlSurface], walk: pd.DataFrame
) -> None:
    est = _estimator(default)
    w = walk[walk[s.TIME_S] < 10.0]
    Z = _inputs(w, est)
    Z[:, 3] = np.nan
    t = w[s.TIME_S].to_numpy()
    out, _ = _run(est, t, Z, retrain=False)
    found, true = t[out["heel_strike"] > 0], t[w[HS].to_numpy() > 0]
    assert abs(found.size - true.size) <= 1
    assert np.median([np.min(np.abs(true - f)) for f in found]) < 0.05


def test_the_phase_toe_off_rule_ends_stance_at_phase_one(
    default: tuple[GPModelSet, ControlSurface], walk: pd.DataFrame
) -> None:
    est = _estimator(default, GPEKFConfig(toe_off="phase"))
    w = walk[walk[s.TIME_S] < 8.0]
    out, _ = _run(est, w[s.TIME_S].to_numpy(), _inputs(w, est), retrain=False)
    ends = np.flatnonzero(out["toe_off"] > 0)
    assert ends.size >= 6
    assert np.all(out["phase"][ends - 1] > 0.95) and np.all(out["in_stance"][ends] == 0.0)


# --- any input ----------------------------------------------------------------------------------------
ANY = st.one_of(st.floats(), st.floats(-200.0, 200.0), st.sampled_from([0.0, 1e308, -1e308, 5e-324]))
DT = st.one_of(st.just(0.005), st.floats(1e-6, 0.05), st.floats(0.05, 3.0))


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    samples=st.lists(
        st.tuples(DT, st.lists(ANY, min_size=3, max_size=3), st.sampled_from([0.0, 1.0, math.nan]), ANY, ANY),
        min_size=1,
        max_size=80,
    )
)
def test_outputs_are_finite_on_any_input(
    default: tuple[GPModelSet, ControlSurface], samples: list[tuple[float, list[float], float, float, float]]
) -> None:
    est = _estimator(default)
    assert isinstance(est, Estimator)
    t = 0.0
    for dt, joints, hs, foot, foot_vel in samples:
        t += dt
        y = est.step(t, np.array([*joints, hs, foot, foot_vel]))
        assert y.shape == (len(est.outputs),) and np.all(np.isfinite(y)), y
        assert 0.0 <= y[0] <= 1.0 and y[1] >= 0.0 and 0.0 <= y[5] <= 30.0 and 0.0 <= y[6] <= 1.0
        P = est.covariance
        assert np.all(np.isfinite(est.state)) and np.all(np.isfinite(P))
        assert P[0, 1] == P[1, 0] and np.linalg.eigvalsh(P).min() >= -1e-12

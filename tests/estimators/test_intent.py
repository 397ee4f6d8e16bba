"""The buttressed Kalman filter (seed 001) against a direct transcription of the paper's equations."""

from __future__ import annotations

import functools
import itertools
import math
from collections.abc import Sequence

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from gaitscope.estimators.intent import ISCI, UNINJURED, BKFConfig, ButtressedKF, D, fit_alpha, fit_kappa
from gaitscope.estimators.intent_estimator import IntentEstimator
from gaitscope.estimators.protocol import input_names
from gaitscope.sessions.synth.trials import sensor_trial

LEG = 0.9


def _direct_touchdown(z: np.ndarray, P: np.ndarray, c: BKFConfig, y: list[float]) -> tuple[np.ndarray, np.ndarray]:
    """Eqs. 1-4 written out as in the paper (and the iSCI current model)."""
    k = np.array(c.kappa)
    vx, vxd = z[3], z[6]
    y_hat = [np.array([vx, vxd - vx, LEG]) @ k]
    H = [np.array([0, 0, 0, k[0] - k[1], 0, 0, k[1]])]
    R = [c.r_t[0]]
    if c.alpha is not None and len(y) > 1:
        a = np.array(c.alpha)
        y_hat.append(np.array([vx, vxd - vx]) @ a)
        H.append(np.array([0, 0, 0, a[0] - a[1], 0, 0, a[1]]))
        R.append(c.r_t[-1])
    Hm = np.array(H)
    S = Hm @ (P + c.q_t * np.eye(7)) @ Hm.T + np.diag(R)
    Si = np.linalg.inv(S)
    z2 = z + P @ Hm.T @ Si @ (np.array(y) - np.array(y_hat))
    P2 = P - P @ Hm.T @ Si @ Hm @ P
    return z2, P2


def _direct_midstance(z: np.ndarray, P: np.ndarray, c: BKFConfig, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eqs. 5-9."""
    z, P = D @ z, D @ P @ D.T + np.diag(c.q_m)
    H = np.eye(6, 7)
    K = P @ H.T @ np.linalg.inv(H @ P @ H.T + np.diag(c.r_m))
    return z + K @ (y - H @ z), (np.eye(7) - K @ H) @ P


def _com(vx: float, side: float, rng: np.random.Generator) -> np.ndarray:
    return np.array([0.02, 0.05 * side, 0.95, vx, 0.1 * side, 0.0]) + rng.normal(0, 1e-3, 6)


@pytest.mark.parametrize("config", [UNINJURED, ISCI], ids=["uninjured", "iSCI"])
def test_each_update_is_the_papers_equations(config: BKFConfig) -> None:
    rng = np.random.default_rng(1)
    f = ButtressedKF(LEG, config)
    f.midstance(_com(1.0, 1, rng))
    z, P = f.z.copy(), f.P.copy()
    side = 1.0
    for step in range(12):
        length = 0.6 + 0.02 * step + rng.normal(0, 0.01)
        current = 10.0 + rng.normal(0, 0.5)
        assert f.touchdown(length, current)
        z, P = _direct_touchdown(z, P, config, [length, current] if config.alpha else [length])
        assert np.allclose(f.z, z, atol=1e-12) and np.allclose(f.P, (P + P.T) / 2, atol=1e-12)
        side = -side
        y = _com(1.0 + 0.03 * step, side, rng)
        f.midstance(y)
        z, P = _direct_midstance(z, (P + P.T) / 2, config, y)
        assert np.allclose(f.z, z, atol=1e-12) and np.allclose(f.P, (P + P.T) / 2, atol=1e-12)
        P = (P + P.T) / 2


def test_a_longer_step_raises_the_desired_speed_before_the_speed_changes() -> None:
    rng = np.random.default_rng(2)
    f = ButtressedKF(LEG)
    k1, _, k3 = UNINJURED.kappa
    steady = 1.0 * k1 + LEG * k3  # the step length of walking at 1 m/s wanting 1 m/s
    side = 1.0
    intents, confidences = [], []
    for step in range(10):
        f.midstance(_com(1.0, side, rng))  # the speed itself never changes here
        intents.append(f.intent)
        confidences.append(f.confidence)
        f.touchdown(steady + (0.08 if step == 6 else 0.0))  # one longer step after mid-stance 6
        side = -side
    assert intents[7] > 0.05 and confidences[7] > 2.0  # at the next mid-stance: speeding up
    assert all(abs(i) < 0.02 for i in intents[2:7])


def test_doubled_and_missed_touchdowns_and_lost_channels_are_survived() -> None:
    rng = np.random.default_rng(3)
    f = ButtressedKF(LEG)
    assert not f.touchdown(0.6)  # before the first mid-stance: nothing to buttress
    f.midstance(_com(1.0, 1, rng))
    assert f.touchdown(0.6) and not f.touchdown(0.9)  # a doubled touchdown is ignored
    f.midstance(_com(1.0, -1, rng))
    f.midstance(_com(1.0, 1, rng))  # a missed touchdown: no intent, no confidence
    assert f.intent == 0.0 and f.confidence == 0.0
    lost = _com(1.0, -1, rng)
    lost[3] = math.nan  # the forward velocity channel lost for a step
    assert f.touchdown(0.6)
    f.midstance(lost)
    assert np.isfinite(f.z).all() and np.isfinite(f.P).all()
    assert not f.touchdown(math.nan)
    with pytest.raises(ValueError, match="leg length"):
        ButtressedKF(0.0)


# --- the stack estimator on a simulated walk: events, faults, holding and recovery ------------------

#: Column of each input channel in ``z``.
COL = {name: i for i, name in enumerate((*IntentEstimator.inputs, *IntentEstimator.optional_inputs))}
SPEED_UP_S = 11.0  # the walk below goes from 1.0 to 1.3 m/s at its 11th stride (about 11.7 s)


@functools.cache
def _walk() -> tuple[tuple[float, ...], np.ndarray, float]:
    """A virtual-cohort walk, 10 strides at 1.0 m/s then 10 at 1.3, at 100 Hz, as the intent estimator's
    inputs (no contact flags: the forces make the events); the matrix is read-only, copy to change it."""
    sensors, leg, _ = sensor_trial([(1.0, 0.0, 10), (1.3, 0.0, 10)], rate_hz=100.0)
    names = input_names(IntentEstimator(leg))
    missing = np.full(len(sensors), np.nan)
    z = np.column_stack([sensors[c].to_numpy(np.float64) if c in sensors else missing for c in names])
    z[:, names.index("foot_contact")] = z[:, names.index("foot_contact_contra")] = np.nan
    z.setflags(write=False)
    return tuple(sensors["time_s"].tolist()), z, leg


def _run(z: np.ndarray, t: Sequence[float] | None = None) -> tuple[IntentEstimator, np.ndarray, np.ndarray]:
    """Every sample through a fresh estimator: the estimator, its outputs ``(n, 5)`` and ``holding`` per sample."""
    times, _, leg = _walk()
    est = IntentEstimator(leg)
    out, held = np.empty((len(z), 5)), np.empty(len(z), dtype=bool)
    for k, (tk, zk) in enumerate(zip(times if t is None else t, z, strict=True)):
        out[k] = est.step(tk, zk)
        held[k] = est.holding
    return est, out, held


def _sped_up(t: Sequence[float], out: np.ndarray, after: float) -> bool:
    """The speed-up (code 1, over 2 SD) reported within two steps of the change of the walk after ``after``."""
    k = np.searchsorted(t, after + 0.7)
    window = out[k : k + 120]  # 1.2 s: two steps
    return bool(((window[:, 2] == 1.0) & (window[:, 3] > 2.0)).any())


def _double_supports(z: np.ndarray) -> list[tuple[int, int]]:
    """``[start, end)`` sample ranges of both feet loaded (over 5 % of the largest force)."""
    f = z[:, [COL["foot_force_N"], COL["foot_force_contra_N"]]]
    both = (f > 0.05 * np.nanmax(f)).all(axis=1)
    edges = np.flatnonzero(np.diff(both.astype(int)))
    return [(int(a) + 1, int(b) + 1) for a, b in itertools.pairwise(edges) if both[a + 1]]


def test_a_clean_walk_reports_the_speed_up_and_never_holds() -> None:
    t, z, _ = _walk()
    _, out, held = _run(z)
    assert _sped_up(t, out, SPEED_UP_S)
    assert not held[300:].any() and np.isfinite(out).all()
    assert (out[np.asarray(t) < SPEED_UP_S, 2] != 1.0).sum() > 900  # mostly steady before it


def test_a_doubled_touchdown_changes_nothing() -> None:
    _, z, _ = _walk()
    _, clean, _ = _run(z)
    bounced = z.copy()
    for a, b in _double_supports(z)[8:12]:
        assert b - a >= 3
        # the contralateral force drops for a sample: a second rising edge
        bounced[(a + b) // 2, COL["foot_force_contra_N"]] = 0.0
    _, out, held = _run(bounced)
    assert np.array_equal(out, clean) and not held[300:].any()


def test_a_missed_touchdown_gives_its_step_no_intent_and_the_next_steps_recover() -> None:
    t, z, _ = _walk()
    missed = z.copy()
    a, b = _double_supports(z)[10]
    missed[a - 5 : b + 5, COL["foot_force_contra_N"]] = 0.0  # no double support: no touchdown
    _, out, held = _run(missed)
    nxt = b + np.flatnonzero(np.any(out[b + 1 :] != out[b:-1], axis=1))[0] + 1  # the next mid-stance
    assert out[nxt, 1] == out[nxt, 2] == out[nxt, 3] == 0.0 and out[nxt, 0] > 0.5
    assert not held[300:].any()
    later = out[nxt + 1 : nxt + 200, 3]
    assert (later > 0.0).any()  # the next step has an intent (and a confidence) again
    assert _sped_up(t, out, SPEED_UP_S)


@pytest.mark.parametrize("channel", ["hip_angle_deg", "hip_angle_contra_deg", "foot_force_N", "foot_force_contra_N"])
def test_a_lost_leg_channel_holds_and_flags_then_recovers(channel: str) -> None:
    t, z, _ = _walk()
    lost = z.copy()
    ts = np.asarray(t)
    gone = (ts >= 5.0) & (ts < 6.5)
    lost[gone, COL[channel]] = np.nan
    _, out, held = _run(lost)
    k0 = int(np.argmax(gone))
    during = (ts > 5.1) & (ts < 6.5)
    assert held[during].all()
    assert (out[during, 1:4] == 0.0).all()  # intent, code and confidence: "not sure"
    assert (out[during, 0] == out[k0 - 1, 0]).all() and (out[during, 4] == out[k0 - 1, 4]).all()  # held
    assert not held[ts > 9.0].any()  # walking again for a few steps: trusted again
    assert _sped_up(t, out, SPEED_UP_S)


def test_standing_still_holds_and_flags_then_walking_recovers() -> None:
    t, z, leg = _walk()
    rng = np.random.default_rng(4)
    walk_n = np.searchsorted(t, 6.0)
    stand = np.tile(z[walk_n - 1], (500, 1))  # 5 s standing, both feet loaded, hips together, with noise
    com = [COL[c] for c in ("com_forward_m", "com_up_m", "com_forward_vel_m_s", "com_up_vel_m_s")]
    stand[:, com] = [0.0, leg, 0.0, 0.0]
    stand[:, com] += rng.normal(0, 1e-3, (500, 4))
    stand[:, [COL["hip_angle_deg"], COL["hip_angle_contra_deg"]]] = rng.normal(0, 0.5, (500, 2))
    stand[:, [COL["foot_force_N"], COL["foot_force_contra_N"]]] = 350.0 + rng.normal(0, 10.0, (500, 2))
    dt = t[1] - t[0]
    stand_t = [t[walk_n - 1] + dt * (k + 1) for k in range(500)]
    again_t = [stand_t[-1] + dt + x - t[0] for x in t]
    times = [*t[:walk_n], *stand_t, *again_t]
    _, out, held = _run(np.vstack([z[:walk_n], stand, z]), times)
    ts = np.asarray(times)
    standing = (ts > stand_t[0] + 2.1) & (ts <= stand_t[-1])
    assert held[standing].all() and (out[standing, 1:4] == 0.0).all()
    k0 = int(np.argmax(held & (ts > stand_t[0])))  # where the hold began
    assert (out[standing, 0] == out[k0 - 1, 0]).all()  # the desired speed held
    assert not held[ts > again_t[0] + 4.0].any()
    assert _sped_up(times, out, again_t[0] + SPEED_UP_S)


def test_walking_backwards_holds_and_flags_then_forwards_recovers() -> None:
    t, z, _ = _walk()
    ts = np.asarray(t)
    back = z.copy()
    rev = (ts >= 5.0) & (ts < 8.0)
    back[rev, COL["com_forward_m"]] *= -1.0  # the centre of mass behind the foot, moving backwards
    back[rev, COL["com_forward_vel_m_s"]] *= -1.0
    _, out, held = _run(back)
    during = (ts > 5.7) & (ts < 8.0)  # from the first mid-stance walking backwards
    assert held[during].all() and (out[during, 1:4] == 0.0).all()
    k0 = int(np.argmax(held & (ts >= 5.0)))  # the mid-stance that started the hold
    assert (out[during, 0] == out[k0 - 1, 0]).all()  # the desired speed of the touchdown before, held
    assert not held[ts > 10.5].any()
    assert _sped_up(t, out, SPEED_UP_S)


ANY = st.floats(allow_nan=True, allow_infinity=True, allow_subnormal=True)


@settings(max_examples=60, deadline=None)
@given(
    corruptions=st.lists(st.tuples(st.integers(0, 399), st.integers(0, 13), ANY), max_size=60),
    noise=st.lists(st.lists(ANY, min_size=14, max_size=14), max_size=20),
    dts=st.lists(st.floats(1e-6, 3.0), min_size=20, max_size=20),
)
def test_any_input_never_raises_and_every_output_is_finite(
    corruptions: list[tuple[int, int, float]], noise: list[list[float]], dts: list[float]
) -> None:
    """The first 4 s of the walk with arbitrary values in arbitrary places, then arbitrary samples at
    arbitrary (increasing) times: every output finite, the code one of -1, 0, 1, the confidence >= 0."""
    t, z, leg = _walk()
    bad = z[:400].copy()
    for k, c, v in corruptions:
        bad[k, c] = v
    est = IntentEstimator(leg)
    times = [*t[:400], *(t[399] + np.cumsum(dts[: len(noise)]))]
    for tk, zk in zip(times, [*bad, *np.array(noise).reshape(-1, 14)], strict=True):
        y = est.step(float(tk), zk)
        assert y.shape == (5,) and np.isfinite(y).all()
        assert y[2] in (-1.0, 0.0, 1.0) and y[3] >= 0.0


def test_the_regressions_recover_kappa_and_alpha_with_seed_001s_labels() -> None:
    rng = np.random.default_rng(1)
    kappa, alpha = np.array([0.25, 0.35, 0.42]), np.array([8.6, 4.2])
    walks, currents, legs = [], [], []
    for leg in (0.82, 0.9, 0.95):
        v0 = rng.uniform(0.8, 1.4, 40)
        v1 = v0 + rng.normal(0, 0.1, 40)
        walks.append((v0, v1, kappa[0] * v0 + kappa[1] * (v1 - v0) + kappa[2] * leg))
        currents.append((v0, v1, alpha[0] * v0 + alpha[1] * (v1 - v0)))
        legs.append(leg)
    assert np.allclose(fit_kappa(walks, legs), kappa)
    assert np.allclose(fit_alpha(currents), alpha)
    gappy = (np.r_[walks[0][0], np.nan], np.r_[walks[0][1], 1.0], np.r_[walks[0][2], 0.7])
    assert np.allclose(fit_kappa([gappy, *walks[1:]], legs), kappa)  # a step with a lost value is left out
    with pytest.raises(ValueError, match="at least 4 steps"):
        fit_kappa([(np.ones(2), np.ones(2), np.ones(2))], [0.9])

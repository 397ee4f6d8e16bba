"""The buttressed Kalman filter (seed 001) against a direct transcription of the paper's equations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from estimators.intent import ISCI, UNINJURED, BKFConfig, ButtressedKF, D

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

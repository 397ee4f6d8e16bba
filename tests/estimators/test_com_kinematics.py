"""The centre of mass from leg kinematics, against forward kinematics by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gaitscope.estimators.com_kinematics import KinematicCoM, LegGeometry, com_from_legs

G = LegGeometry(0.42, 0.41, 0.07)


def _com(thigh: float, shank: float, w_th: float, w_sh: float, force: float, force_c: float) -> np.ndarray:
    # the other leg gets angles far from these so picking the wrong one shows
    return com_from_legs(G, thigh, shank, w_th, w_sh, force, -thigh - 30, -shank - 30, 50.0, 50.0, force_c)


def test_upright_leg_puts_the_pelvis_above_the_ankle() -> None:
    out = _com(0.0, 0.0, 0.0, 0.0, 700.0, 0.0)
    assert out[0] == pytest.approx(0.0, abs=1e-12)
    assert out[2] == pytest.approx(0.42 + 0.41 + 0.07)
    assert np.isnan(out[1]) and np.isnan(out[4])  # lateral: not observable


def test_position_and_velocity_match_hand_computed_forward_kinematics() -> None:
    th, sh, wth, wsh = -20.0, 10.0, -90.0, -40.0  # thigh extending behind, shank forward
    out = _com(th, sh, wth, wsh, 600.0, 50.0)
    r = math.radians
    x = -(0.42 * math.sin(r(th)) + 0.41 * math.sin(r(sh)))
    vx = -(0.42 * math.cos(r(th)) * r(wth) + 0.41 * math.cos(r(sh)) * r(wsh))
    assert out[0] == pytest.approx(x)
    assert out[3] == pytest.approx(vx)
    assert vx > 0  # the body moves forward over a stance leg whose segments rotate backward
    # numerical derivative of the position agrees with the velocity
    dt = 1e-4
    later = _com(th + wth * dt, sh + wsh * dt, wth, wsh, 600.0, 50.0)
    assert (later[0] - out[0]) / dt == pytest.approx(out[3], rel=1e-3)
    assert (later[2] - out[2]) / dt == pytest.approx(out[5], rel=1e-3)


def test_the_loaded_foot_is_the_stance_foot_and_unknown_forces_give_nan() -> None:
    a = _com(-10.0, 5.0, 0.0, 0.0, 100.0, 600.0)  # the other foot carries the load
    b = com_from_legs(G, -10.0, 5.0, 0.0, 0.0, 600.0, 20.0, -35.0, 0.0, 0.0, 100.0)
    assert a[0] == pytest.approx(-(0.42 * math.sin(math.radians(-20.0)) + 0.41 * math.sin(math.radians(-35.0))))
    assert b[0] != pytest.approx(a[0])
    assert np.isnan(_com(0.0, 0.0, 0.0, 0.0, math.nan, 0.0)).all()


def test_geometry_from_leg_length_uses_winters_fractions() -> None:
    g = LegGeometry.from_leg_length(0.9)
    assert g.thigh_m == pytest.approx(0.9 / 0.53 * 0.245)
    assert g.thigh_m + g.shank_m + g.ankle_height_m == pytest.approx(0.9, rel=0.01)
    with pytest.raises(ValueError, match="leg length"):
        LegGeometry.from_leg_length(math.nan)


def test_the_stack_estimator_matches_the_function_and_holds_when_inputs_go_bad() -> None:
    from hypothesis import given, settings
    from hypothesis import strategies as st

    est = KinematicCoM(0.9)
    assert [n for n, _ in est.outputs] == ["com_forward_m", "com_up_m", "com_forward_vel_m_s", "com_up_vel_m_s"]
    z = np.array([-10.0, -60.0, 5.0, -30.0, 20.0, 90.0, 10.0, 40.0, 650.0, 30.0])

    def ref(v: np.ndarray) -> np.ndarray:
        th, wth, sh, wsh, thc, wthc, shc, wshc, f, fc = v
        return com_from_legs(est.geometry, th, sh, wth, wsh, f, thc, shc, wthc, wshc, fc)[[0, 2, 3, 5]]

    y = est.step(0.0, z)
    assert np.allclose(y, ref(z))
    z2 = z.copy()
    z2[[8, 9]] = [30.0, 650.0]  # the other foot loaded: the other leg's angles
    assert np.allclose(est.step(0.01, z2), ref(z2))
    assert not np.allclose(est.step(0.02, z2), y)
    bad = z.copy()
    bad[0] = math.inf
    assert np.array_equal(est.step(0.03, bad), est.step(0.04, z2))  # held, then the same estimate

    @settings(max_examples=200, deadline=None)
    @given(st.lists(st.floats(allow_nan=True, allow_infinity=True), min_size=10, max_size=10))
    def finite_whatever(values: list[float]) -> None:
        out = KinematicCoM(0.9).step(0.0, np.array(values))
        assert np.isfinite(out).all() and out.shape == (4,)

    finite_whatever()

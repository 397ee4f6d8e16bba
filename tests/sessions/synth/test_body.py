"""Whole-body columns of a generated walk: the other leg, foot loads, centre of mass, IMU accelerations."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from gaitscope.sessions import schema as s
from gaitscope.sessions.synth.body import COM_HEIGHT_FRAC, STEP_WIDTH_M, second_derivative
from gaitscope.sessions.synth.cohort import CONTRA_EXCURSION_RANGE, CohortSpec, generate_walk, make_subjects

N = 150
SUBJECT = make_subjects(CohortSpec())[0]
V1_COLUMNS = 32


@pytest.fixture(scope="module")
def walks() -> dict[float, pd.DataFrame]:
    return {v: generate_walk(SUBJECT, [(v, 0.0, 12)], np.random.default_rng(4)) for v in (0.8, 1.2)}


def _per_stride(w: pd.DataFrame, col: str) -> np.ndarray:
    return w[col].to_numpy().reshape(-1, N)


def test_second_derivative_on_a_grid_with_repeated_instants() -> None:
    t = np.array([np.linspace(0, 1, 55), np.linspace(1, 2.2, 55)])  # the boundary instant appears twice
    a = second_derivative(t, 3 * t**2 - t)
    np.testing.assert_allclose(a, 6.0, atol=1e-9)
    assert a[0, -1] == a[1, 0]


def test_feet_carry_the_body_with_a_double_hump_that_grows_with_speed(walks: dict[float, pd.DataFrame]) -> None:
    weight = SUBJECT.mass_kg * 9.81
    peaks = {}
    for v, w in walks.items():
        ipsi, contra = _per_stride(w, s.VERTICAL_GRF) / weight, _per_stride(w, s.VERTICAL_GRF_CONTRA) / weight
        total = ipsi + contra
        assert total[:, :-1].mean() == pytest.approx(1.0, abs=0.01)  # the vertical CoM motion averages out
        assert (ipsi >= 0).all() and (contra >= 0).all()
        assert ipsi[:, 0].max() < 1e-9 and (ipsi[:, 100:] == 0).all()  # lands unloaded; swing carries nothing
        first, second = ipsi[:, :40].max(axis=1), ipsi[:, 55:95].max(axis=1)
        valley = ipsi[:, 30:70].min(axis=1)
        assert ((first > 1.04) & (first < 1.35) & (second > 1.04) & (second < 1.35)).all(), v
        assert (valley < np.minimum(first, second) - 0.1).all() and (valley > 0.6).all()
        peaks[v] = first.mean()
    assert peaks[1.2] > peaks[0.8] + 0.08  # Nilsson & Thorstensson's trend: peaks grow with speed


def test_centre_of_mass_relative_to_the_stance_foot(walks: dict[float, pd.DataFrame]) -> None:
    w = walks[1.2]
    fwd, lat, up = (_per_stride(w, c) for c in s.COM_STANCE_POSITION)
    height = COM_HEIGHT_FRAC * SUBJECT.height_m
    assert np.abs(up - height).max() < 0.1  # about the standing height of the CoM, minus the leg's shortening
    assert np.abs(lat).max() < STEP_WIDTH_M and (lat[:, 20:60] > 0).all()  # ipsilateral (right) foot at -w/2
    contra_hs = int(np.argmax(_per_stride(w, s.HEEL_STRIKE_CONTRA)[0]))
    assert (fwd[:, 1] < 0).all() and (fwd[:, contra_hs - 1] > 0).all()  # the CoM passes over the stance foot
    assert (np.diff(fwd[:, 1 : contra_hs - 1], axis=1) > 0).all()
    jump = fwd[:, contra_hs] - fwd[:, contra_hs - 1]
    assert (jump < -0.2).all()  # touchdown: the new stance foot is ahead


def test_imu_mounting_points_accelerate_as_body_segments_do(walks: dict[float, pd.DataFrame]) -> None:
    w = walks[1.2]
    peak = {seg: np.abs(w[list(s.IMU_POINT_ACCELERATION[seg])].to_numpy()).max() for seg in s.IMU_SEGMENTS}
    assert peak["pelvis"] < 5.0  # the trunk moves smoothly
    assert 3.0 < peak["thigh"] < 15.0 and 10.0 < peak["shank"] < 50.0 and 15.0 < peak["foot"] < 80.0
    for seg in ("thigh", "shank", "foot"):
        assert peak[f"{seg}_contra"] == pytest.approx(peak[seg], rel=0.3)


def test_the_other_leg_is_the_same_leg_half_a_cycle_later_with_the_subjects_asymmetry() -> None:
    subjects = make_subjects(CohortSpec())
    for x, (lo, hi) in ((a.contra_knee_excursion, CONTRA_EXCURSION_RANGE[0]) for a in subjects):
        assert lo <= x <= hi
    assert len({a.contra_ankle_excursion for a in subjects}) == 10
    walk = generate_walk(SUBJECT, [(1.0, 0.0, 40)], np.random.default_rng(2))
    ipsi, contra = np.degrees(walk[s.KNEE_ANGLE].to_numpy()), np.degrees(walk[s.KNEE_ANGLE_CONTRA].to_numpy())
    ratio = np.ptp(contra) / np.ptp(ipsi)
    assert ratio == pytest.approx(1 + SUBJECT.contra_knee_excursion, abs=0.02)
    lag = np.argmax([np.corrcoef(np.roll(ipsi, k), contra)[0, 1] for k in range(0, N)])
    assert abs(lag - N // 2) <= 3  # half a cycle


def test_new_columns_leave_the_existing_ones_and_their_random_streams_alone() -> None:
    walk = generate_walk(SUBJECT, [(1.0, 5.0, 5)], np.random.default_rng(9))
    other = generate_walk(replace(SUBJECT, contra_knee_excursion=0.3, contra_ankle_excursion=-0.3), [(1.0, 5.0, 5)],
                          np.random.default_rng(9))  # fmt: skip
    old = list(walk.columns[:V1_COLUMNS])
    pd.testing.assert_frame_equal(walk[old], other[old])
    assert not np.allclose(walk[s.KNEE_ANGLE_CONTRA], other[s.KNEE_ANGLE_CONTRA])
    np.testing.assert_array_equal(walk[s.HIP_ANGLE_CONTRA], other[s.HIP_ANGLE_CONTRA])  # the hip takes none

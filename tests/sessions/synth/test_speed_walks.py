"""Seed 003's protocol on the cohort: a sinusoidal treadmill speed, then a sudden stop and standing."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from gaitscope.sessions.synth.cohort import CohortSpec, make_subjects
from gaitscope.sessions.synth.speed_walks import SpeedProtocol, speed_at, speed_walk

SUBJECT = make_subjects(CohortSpec())[1]
PROTOCOL = SpeedProtocol(walk_s=25.0, standing_s=2.0)


@pytest.fixture(scope="module")
def walk() -> pd.DataFrame:
    return speed_walk(SUBJECT, PROTOCOL)


def test_the_speed_follows_the_sinusoid_and_the_cadence_follows_the_speed(walk: pd.DataFrame) -> None:
    walking = walk[walk["condition"] == "walking"]
    assert walking["gt_speed_m_s"].min() == pytest.approx(0.4, abs=0.05)
    assert walking["gt_speed_m_s"].max() == pytest.approx(1.2, abs=0.05)
    assert float(speed_at(5.0, PROTOCOL)) == pytest.approx(1.2)
    # stance is shorter (its phase rate higher) when the walker is fast
    fast = walking["gt_speed_m_s"] > 1.1
    slow = walking["gt_speed_m_s"] < 0.5
    assert walking.loc[fast, "gt_stance_rate"].median() > 1.5 * walking.loc[slow, "gt_stance_rate"].median()
    stance = walking["gt_stance_phase"].dropna()
    assert stance.between(0, 1).all() and 0.5 < len(stance) / len(walking) < 0.75  # stance about 60 %
    assert walking["heel_strike"].sum() == pytest.approx(walking["toe_off"].sum(), abs=1)


def test_a_sudden_stop_freezes_the_walker(walk: pd.DataFrame) -> None:
    cond = walk["condition"].to_numpy()
    assert list(dict.fromkeys(cond)) == ["walking", "stopping", "standing"]
    standing = walk[cond == "standing"]
    assert (standing["gt_stance_rate"].fillna(0) == 0).all() and standing["heel_strike"].sum() == 0
    assert standing["knee_angle_deg"].std() < 0.2  # the encoders read a still leg
    # stopped in stance (the stop begins at gait phase 0.25), where the stance phase freezes
    assert standing["gt_stance_phase"].notna().all() and standing["gt_stance_phase"].nunique() == 1
    swing = speed_walk(SUBJECT, SpeedProtocol(walk_s=25.0, standing_s=2.0, stop_phase=0.75))
    assert swing.loc[swing["condition"] == "standing", "gt_stance_phase"].isna().all()
    t = walk["time_s"].to_numpy()
    assert np.all(np.diff(t) > 0) and np.allclose(np.diff(t), 1 / PROTOCOL.rate_hz, atol=1e-6)


def test_the_walk_is_deterministic_and_bad_protocols_are_refused(walk: pd.DataFrame) -> None:
    assert speed_walk(SUBJECT, PROTOCOL).equals(walk)
    with pytest.raises(ValueError, match="speeds"):
        SpeedProtocol(speed_range_m_s=(1.2, 0.4))

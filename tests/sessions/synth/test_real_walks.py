"""Real-walking effects on top of the cohort: bouts from and to standing, turns, offsets, dropouts."""

from __future__ import annotations

import numpy as np

from gaitscope.sessions import schema as s
from gaitscope.sessions.synth.cohort import CohortSpec, make_subjects
from gaitscope.sessions.synth.real_walks import CONDITIONS, RealWalkSpec, real_walk

SUBJECT = make_subjects(CohortSpec())[2]


def test_a_walk_has_every_condition_in_bouts_between_standing() -> None:
    f = real_walk(SUBJECT)
    assert set(f["condition"]) == set(CONDITIONS)
    t = f[s.REPLAY_TIME].to_numpy()
    assert np.all(np.diff(t) > 0)
    still = f["condition"].to_numpy() == "standing"
    assert still[0] and still[-1]
    assert np.isnan(f.loc[still, "gt_phase"]).all() and (f.loc[still, "gt_phase_rate"] == 0).all()
    walking = f.loc[~still, "gt_phase"]
    assert walking.between(0, 1).all()
    # three bouts: three stretches of walking
    assert np.count_nonzero(np.diff(still.astype(int)) == -1) == 3
    # each bout starts and ends at rest in mid-stance (the rest phase), not at a heel strike
    ends = np.flatnonzero(np.diff(still.astype(int)) != 0)
    phase = f["gt_phase"].to_numpy()
    assert np.allclose(phase[ends[0::2] + 1], RealWalkSpec().rest_phase, atol=0.02)
    assert np.allclose(phase[ends[1::2]], RealWalkSpec().rest_phase, atol=0.02)
    assert np.isclose(real_walk(SUBJECT, RealWalkSpec(rest_phase=0.0))["gt_phase"].dropna().min(), 0.0)
    # standing is still: small angular velocities (a fifth of walking's gyro noise), no heel strikes
    assert f.loc[still, "foot_vel_dps"].abs().median() < 10 and f.loc[still, s.REPLAY_HEEL_STRIKE].sum() == 0


def test_sensor_faults_are_there_and_the_walk_is_deterministic() -> None:
    a, b = real_walk(SUBJECT), real_walk(SUBJECT)
    assert a.equals(b)
    assert a[list(s.REPLAY_SIGNALS)].isna().any().any()  # dropouts
    clean = real_walk(SUBJECT, RealWalkSpec(dropouts_per_min=0.0))
    assert not clean[list(s.REPLAY_SIGNALS)].isna().any().any()
    turns = clean["condition"] == "turn"
    assert 0 < turns.mean() < 0.5

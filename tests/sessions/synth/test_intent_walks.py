"""Speed-change walks: the command changes the desired speed, the step length leads the speed."""

from __future__ import annotations

import numpy as np
import pytest

from gaitscope.sessions.synth.cohort import CohortSpec, make_subjects
from gaitscope.sessions.synth.intent_walks import IntentProtocol, commanded_trial, self_paced_trial, speed_profile

SUBJECT = make_subjects(CohortSpec())[3]


@pytest.mark.parametrize("direction", [1, -1])
def test_a_commanded_trial_changes_the_desired_speed_at_the_command_stride(direction: int) -> None:
    p = IntentProtocol()
    trial = commanded_trial(SUBJECT, direction, 0, p)
    d = trial.desired_m_s
    assert np.all(d[: p.strides_before] == d[0])
    assert np.all(d[p.strides_before :] == d[-1])
    assert np.sign(d[-1] - d[0]) == direction
    assert p.change_range_m_s[0] <= abs(d[-1] - d[0]) <= p.change_range_m_s[1]
    assert trial.command_time_s == pytest.approx(trial.stride_start_s[p.strides_before])
    # the walker ends near the desired speed, as the sensors see it
    f = trial.sensors
    late = f["time_s"] > trial.stride_start_s[-2]
    assert f.loc[late, "gt_speed_m_s"].mean() == pytest.approx(d[-1], abs=0.08)
    for name in ("com_forward_m", "com_forward_vel_m_s", "hip_angle_deg", "hip_angle_contra_deg",
                 "foot_force_N", "foot_force_contra_N", "step_length_m"):  # fmt: skip
        assert np.isfinite(f[name]).all(), name


def test_the_step_length_leads_the_speed() -> None:
    """With a lead, the first strides after the command are longer (speed-up) than the speed alone gives."""
    rng = np.random.default_rng(0)
    desired = np.r_[np.full(4, 1.0), np.full(6, 1.3)]
    quiet = IntentProtocol(speed_cv=0.0)
    v, scale = speed_profile(desired, 1.0, 0.9, quiet, rng)
    assert np.all(np.diff(v[3:]) > 0) and v[-1] == pytest.approx(1.3, abs=0.01)
    assert np.allclose(scale[:4], 1.0)
    assert scale[4] > scale[6] > 1.0  # leads most where speed lags most
    _, no_lead = speed_profile(desired, 1.0, 0.9, IntentProtocol(speed_cv=0.0, step_lead=0.0), rng)
    assert np.allclose(no_lead, 1.0)


def test_trials_are_deterministic_and_self_paced_walks_change_speed_several_times() -> None:
    p = IntentProtocol()
    a, b = self_paced_trial(SUBJECT, 0, p), self_paced_trial(SUBJECT, 0, p)
    assert a.sensors.equals(b.sensors)
    assert a.direction == 0 and np.isnan(a.command_time_s)
    assert np.count_nonzero(np.diff(a.desired_m_s)) >= 3
    assert np.all((a.desired_m_s >= 0.5) & (a.desired_m_s <= 1.7))


def test_bad_protocols_are_refused() -> None:
    with pytest.raises(ValueError, match="step_lead"):
        IntentProtocol(step_lead=1.5)
    with pytest.raises(ValueError, match="strides_before"):
        IntentProtocol(strides_before=1)
    with pytest.raises(ValueError, match="direction"):
        commanded_trial(SUBJECT, 0, 0, IntentProtocol())

"""Calibrating a fingerprint from a walk: which strides serve, what is left out and why, and refusals."""

from __future__ import annotations

import numpy as np
import pytest

from gaitscope.sessions.formats.models import default_model_path, load_model
from gaitscope.sessions.personalization.calibration import MIN_STRIDES, CalibrationRefused, CalibrationWalk, calibrate
from gaitscope.sessions.synth.trials import sensor_trial


def _walk(strides: int = 20) -> CalibrationWalk:
    s, _, _ = sensor_trial([(1.0, 0.0, strides)], rate_hz=100.0)
    return CalibrationWalk(
        t=s["time_s"].to_numpy(float),
        thigh_deg=s["thigh_angle_deg"].to_numpy(float),
        heel_strike=s["heel_strike"].to_numpy() > 0.5,
        belt_m_s=s["gt_speed_m_s"].to_numpy(float),
        stride_estimate_m=s["gt_stride_length_m"].to_numpy(float),
    )


FMAP = load_model(default_model_path())[0].fingerprints
assert FMAP is not None


def test_a_clean_walk_uses_every_stride_and_fits_better_than_the_average() -> None:
    walk = _walk()
    cal = calibrate(FMAP, walk)
    assert cal.strides_used == int(walk.heel_strike.sum()) - 1 and cal.excluded == {}
    assert cal.stride_length_source == "belt speed"
    assert cal.fit_rmse_personal_deg < cal.fit_rmse_avg_deg
    assert cal.seconds_used == pytest.approx(
        walk.t[np.flatnonzero(walk.heel_strike)[-1]] - walk.t[np.flatnonzero(walk.heel_strike)[0]]
    )


def test_spoiled_strides_are_left_out_by_reason_and_the_rest_still_fit() -> None:
    walk = _walk(24)
    hs = np.flatnonzero(walk.heel_strike)
    thigh = walk.thigh_deg.copy()
    thigh[hs[1] + 5 : hs[1] + 9] = np.nan  # a dropout in stride 1
    thigh[hs[3] : hs[4]] = thigh[hs[3]]  # stride 3: no thigh motion (standing)
    t = walk.t.copy()
    t[hs[6] + 10 :] += 0.5  # a gap of half a second inside stride 6
    belt = walk.belt_m_s.copy()
    belt[hs[8] : hs[10]] = np.nan  # strides 8 and 9: no belt speed, the estimate instead
    spoiled = CalibrationWalk(t, thigh, walk.heel_strike, belt, walk.stride_estimate_m)
    cal = calibrate(FMAP, spoiled)
    assert cal.excluded == {
        "thigh angle missing": 1,
        "under 10 deg of thigh motion (standing?)": 1,
        "a gap of over 0.1 s": 1,
    }
    assert cal.strides_used == hs.size - 1 - 3
    assert cal.stride_length_source == "belt speed and the recorded estimate"
    clean = calibrate(FMAP, walk)
    assert np.allclose(cal.fingerprint, clean.fingerprint, atol=0.3)


def test_standing_or_a_short_walk_is_refused_saying_why() -> None:
    walk = _walk(MIN_STRIDES - 3)
    with pytest.raises(CalibrationRefused, match=f"walk at least {MIN_STRIDES} steady strides"):
        calibrate(FMAP, walk)
    standing = CalibrationWalk(
        walk.t, np.full(walk.t.size, 5.0), walk.heel_strike, walk.belt_m_s, walk.stride_estimate_m
    )
    with pytest.raises(CalibrationRefused, match="standing"):
        calibrate(FMAP, standing)
    still = CalibrationWalk(walk.t, walk.thigh_deg, np.zeros(walk.t.size, bool), walk.belt_m_s, walk.stride_estimate_m)
    with pytest.raises(CalibrationRefused, match="fewer than two heel strikes"):
        calibrate(FMAP, still)

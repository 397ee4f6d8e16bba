"""The peak torque a session's settings command over a stride (gaitscope.sessions.peak_torque): the stack's
command at its maximum over the phase, checked against the streaming path, the gain, the bound and the boost."""

from __future__ import annotations

import math

import numpy as np
import pytest

from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.sessions.peak_torque import PHASES, peak_torque
from gaitscope.sessions.stack import NOMINAL_STRIDE

MASS = 70.0


def _peak(model: TrainedModel, **kw: float) -> float:
    args = {"mass_kg": MASS, "stride_legs": 1.3, "incline_deg": 0.0, "torque_gain": 1.0, "max_torque_Nm": 80.0}
    return peak_torque(model.torque, **{**args, **kw})


def test_the_peak_is_the_streaming_command_at_its_largest(small_model: TrainedModel) -> None:
    streamed = [small_model.torque.torque_at(float(p), 1.3, 5.0, MASS, 80.0) for p in PHASES]
    assert _peak(small_model, incline_deg=5.0) == pytest.approx(max(streamed), abs=1e-9)
    assert 5.0 < max(streamed) < 80.0  # a real plantarflexion peak, not clipped


def test_the_peak_scales_with_the_gain_and_the_boost_and_stops_at_the_bound(small_model: TrainedModel) -> None:
    one = _peak(small_model)
    assert _peak(small_model, torque_gain=1.8) == pytest.approx(1.8 * one)
    assert _peak(small_model, torque_gain=1.5, intent_gain_boost=0.2) == pytest.approx(1.8 * one)
    assert _peak(small_model, torque_gain=3.0, max_torque_Nm=10.0) == 10.0
    assert _peak(small_model, torque_gain=0.0) == 0.0
    assert _peak(small_model, max_torque_Nm=0.0) == 0.0


def test_an_unknown_gait_state_is_the_nominal_one(small_model: TrainedModel) -> None:
    nominal = _peak(small_model, stride_legs=NOMINAL_STRIDE, incline_deg=0.0)
    assert _peak(small_model, stride_legs=math.nan, incline_deg=math.nan) == nominal
    assert _peak(small_model, stride_legs=math.inf, incline_deg=-math.inf) == nominal


def test_the_peak_depends_on_the_gait_state(small_model: TrainedModel) -> None:
    peaks = [_peak(small_model, incline_deg=r) for r in (-10.0, 0.0, 10.0)]
    assert len({round(p, 3) for p in peaks}) == 3  # incline moves the profile's peak
    assert np.all(np.isfinite(peaks))


def test_a_primary_with_its_own_torque_peaks_at_the_bound() -> None:
    args = {"mass_kg": MASS, "stride_legs": 1.3, "incline_deg": 0.0, "torque_gain": 0.5}
    assert peak_torque(None, max_torque_Nm=25.0, **args) == 25.0

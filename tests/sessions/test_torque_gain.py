"""The one owner of the effective torque gain (:mod:`gaitscope.sessions.torque_gain`): the set gain, the soft
start's ramp and the intent boost, and what the stack is told."""

from __future__ import annotations

import math

import numpy as np

from gaitscope.sessions.schema import SessionSettings
from gaitscope.sessions.torque_gain import TorqueGain


class _Stack:
    """The stack's side of the gain: what it was last told, and an intent estimator's outputs."""

    names = ("intent",)
    outputs = (("intent_code", "intent_confidence"),)

    def __init__(self) -> None:
        self.told: list[tuple[float, float]] = []

    def retune_torque(self, gain: float, bound: float) -> None:
        self.told.append((gain, bound))


def test_the_ramp_caps_the_set_gain_and_bound_until_both_are_reached() -> None:
    stack = _Stack()
    gain = TorqueGain(stack, SessionSettings(torque_gain=1.0, max_torque_Nm=15.0), soft_start=True)  # type: ignore[arg-type]
    gain.set(gain.settings, 0.0)
    assert stack.told == [(1.0, 15.0), (0.0, 0.0)]
    gain.before_step(1.0)
    assert stack.told[-1] == (0.5, 10.0) and gain.ramping
    gain.before_step(2.0)
    assert stack.told[-1] == (1.0, 15.0) and not gain.ramping
    n = len(stack.told)
    gain.before_step(3.0)  # the ramp is over: the stack is not told again
    assert len(stack.told) == n
    gain.restart(3.0)  # the primary restarted: from 0 again
    assert stack.told[-1] == (0.0, 0.0) and gain.ramping


def test_without_a_soft_start_the_stack_runs_at_the_set_gain() -> None:
    stack = _Stack()
    gain = TorqueGain(stack, SessionSettings(torque_gain=0.8, max_torque_Nm=12.0), soft_start=False)  # type: ignore[arg-type]
    gain.set(SessionSettings(torque_gain=0.9, max_torque_Nm=12.0), 5.0)
    gain.restart(6.0)
    gain.before_step(6.0)
    assert stack.told == [(0.9, 12.0)]


def test_the_boost_moves_the_torque_within_the_ramps_headroom() -> None:
    stack = _Stack()
    s = SessionSettings(torque_gain=1.0, max_torque_Nm=15.0, intent_gain_boost=0.3)
    gain = TorqueGain(stack, s, soft_start=True)  # type: ignore[arg-type]
    speeding_up = [np.array([1.0, 10.0])]
    assert gain.torque(0.0, speeding_up, 4.0) == 0.0  # the ramp's bound is 0 at its start
    for k in range(1, 41):
        out = gain.torque(k * 0.05, speeding_up, 4.0)
    # 2 s in: the ramp's gain is 1.0, the set gain's: no headroom over it, so the torque is not raised
    assert out == 4.0 and math.isclose(gain.boost.value, 0.3)
    assert math.isclose(gain.torque(2.5, speeding_up, 4.0), 4.0 * 1.25)  # the ramp's 1.25 over the set 1.0
    assert math.isclose(gain.torque(3.0, speeding_up, 4.0), 4.0 * 1.3)  # the whole boost
    off = TorqueGain(stack, s, soft_start=False)  # type: ignore[arg-type]
    for k in range(41):
        out = off.torque(k * 0.05, speeding_up, 4.0)
    assert math.isclose(out, 4.0 * 1.3)

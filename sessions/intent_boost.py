"""Assistance follows intent: the torque gain raised while the walker speeds up, lowered while they slow down.

Beyond seed 001 (the paper estimates intent, it does not act on it), optional and off by default: the
session setting ``intent_gain_boost`` (:data:`~gaitscope.sessions.schema.SETTING_LIMITS`, 0..0.3, 0: off) is the
largest fraction by which the gain moves. The rule, per sample:

- **target** ``b* = boost x code x min(confidence / SATURATION_SD, 1)``: ``code`` is the stack's ``intent``
  estimator's ``intent_code`` (1 speeding up, -1 slowing down, 0 steady or not sure) and ``confidence`` its
  ``intent_confidence`` (the change of desired speed in standard deviations), so a barely significant
  intent moves the gain a little and one of :data:`SATURATION_SD` or more the whole ``boost``. Slowing
  down lowers the gain by the same rule (less push-off helps a walker who wants to slow down, and a
  symmetric rule has no bias over a walk whose speed comes back). No intent estimator in the stack, a
  failed one, a NaN or infinite code, or the estimator holding ("not sure", confidence 0): ``b* = 0``.
- **ramp**: the effective boost ``b`` moves towards ``b*`` at most at the rate the runtime ramps a gain
  change (``SETTING_LIMITS["torque_gain"]``'s 0.5 gain/s): ``|db/dt| <= 0.5 / max(gain, 1)``, so the
  effective gain ``gain x (1 + b)`` never moves faster than 0.5/s on account of intent, and a sudden
  intent never steps the torque. Times are session times (deterministic: a re-run can reproduce it).
- **torque** ``clamp(torque x min(1 + b, headroom), 0, bound)``: the stack's torque is already within the
  bound and ``1 + b`` is within ``[0.7, 1.3]``, so the command stays finite and within the bound whatever
  the intent says. The stack's torque is linear in the gain below the bound, so this is the torque at the
  gain ``gain x (1 + b)``. During the soft start (:class:`gaitscope.sessions.estimation.FrameEstimator`) ``bound`` is
  the ramped bound and ``headroom`` what the ramp allows over the ramped gain (1 while the gain itself
  ramps): the boost never lifts the torque above the soft start's ramp.

Pure computation, a few float operations per sample (nothing at all while the setting and ``b`` are 0).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Final

import numpy as np
from numpy.typing import NDArray

from gaitscope.sessions.schema import SETTING_LIMITS

__all__ = ["INTENT", "MAX_STEP_S", "SATURATION_SD", "IntentBoost"]

#: The registry name of the speed-change intent estimator.
INTENT: Final = "intent"
#: Confidence (standard deviations of the desired speed) at which the boost reaches the setting.
SATURATION_SD: Final = 3.0
#: Longest time step the ramp takes in one sample (s): a late sample does not buy a large step.
MAX_STEP_S: Final = 0.05
_GAIN_RATE: Final = SETTING_LIMITS["torque_gain"][2]
_BOOST_MAX: Final = SETTING_LIMITS["intent_gain_boost"][1]


class IntentBoost:
    """The effective boost of one session (see the module docstring).

    Args:
        names: the stack's estimator names; outputs: each one's output names (``EstimatorStack.outputs``).

    Attributes:
        value: the effective boost ``b`` now (a fraction of the gain, within ``[-0.3, 0.3]``).
        target: what it ramps towards.
    """

    def __init__(self, names: Sequence[str], outputs: Sequence[Sequence[str]]):
        self._k: int | None = None
        self._code = self._confidence = 0
        if INTENT in names:
            k = list(names).index(INTENT)
            outs = list(outputs[k])
            if "intent_code" in outs and "intent_confidence" in outs:
                self._k, self._code, self._confidence = k, outs.index("intent_code"), outs.index("intent_confidence")
        self.value = 0.0
        self.target = 0.0
        self._t: float | None = None

    def active(self, boost: float) -> bool:
        """True when the boost may change the torque (the setting is on, or the effective boost is not yet 0)."""
        return boost != 0.0 or self.value != 0.0

    def update(self, t: float, outputs: Sequence[NDArray[np.float64] | None], boost: float, gain: float) -> float:
        """The effective boost at session time ``t``, from the stack's ``outputs`` of this sample, the session's
        ``intent_gain_boost`` and its torque gain."""
        if not 0.0 <= boost <= _BOOST_MAX:  # NaN too: off
            boost = 0.0
        target = 0.0
        k = self._k
        y = outputs[k] if k is not None and k < len(outputs) else None
        if y is not None and boost > 0.0:
            code, confidence = float(y[self._code]), float(y[self._confidence])
            if confidence > 0.0 and (code > 0.5 or code < -0.5):  # NaN compares False
                scale = min(confidence / SATURATION_SD, 1.0)
                target = boost * scale if code > 0 else -boost * scale
        self.target = target
        last, self._t = self._t, t
        dt = t - last if last is not None else 0.0
        if not dt > 0.0:  # the first sample, or a time that did not advance (or NaN)
            dt = 0.0
        rate = _GAIN_RATE / max(gain, 1.0) if gain == gain else _GAIN_RATE
        step = rate * min(dt, MAX_STEP_S)
        self.value += min(max(target - self.value, -step), step)
        if not -_BOOST_MAX <= self.value <= _BOOST_MAX:
            self.value = 0.0
        return self.value

    def torque(self, torque: float, bound: float, headroom: float = math.inf) -> float:
        """``torque x min(1 + value, headroom)`` within ``[0, bound]``; 0 when anything is not a finite number.
        ``headroom``: the most the factor may be (the soft start's, while it ramps; at least 1)."""
        out = torque * min(1.0 + self.value, headroom)
        if not (math.isfinite(out) and math.isfinite(bound)):
            return 0.0
        return min(max(out, 0.0), max(bound, 0.0))

"""The one owner of a session's effective torque gain and bound.

Three things move the gain the device's torque is computed at, and they used to write it each in turn:
the clinician's setting (``torque_gain``, ``max_torque_Nm``), the soft start's ramp (from the first frame and
after every restart of the primary, the gain and bound grow from 0 at the rate limits of
:data:`~gaitscope.sessions.schema.SETTING_LIMITS`: 0.5 gain/s, 10 N m/s) and the intent boost
(:mod:`gaitscope.sessions.intent_boost`, ``intent_gain_boost``, off by default). :class:`TorqueGain` holds
all three and is the only one that tells the stack its gain (:meth:`EstimatorStack.retune_torque`); everyone
else asks it. Deterministic in session time, so a re-run reproduces it.

- **set** (:meth:`TorqueGain.set`): the settings in effect; the stack runs at them unless the ramp caps them.
- **ramp**: while it runs, the stack's gain and bound are ``min(set, rate x (t - t0))``; it ends once both
  reached the set values, and restarts (:meth:`TorqueGain.restart`) with the primary.
- **boost**: the stack's torque times ``min(1 + b, headroom)`` within the bound, where during the ramp
  ``headroom`` is what the ramp allows over the gain the stack runs at, so the boost never lifts the torque
  above the soft start's ramp.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from gaitscope.sessions.intent_boost import IntentBoost
from gaitscope.sessions.schema import SETTING_LIMITS, SessionSettings

if TYPE_CHECKING:
    from gaitscope.sessions.stack import EstimatorStack

__all__ = ["TorqueGain", "safe_torque"]

_GAIN_RATE = SETTING_LIMITS["torque_gain"][2]
_BOUND_RATE = SETTING_LIMITS["max_torque_Nm"][2]


class TorqueGain:
    """The effective torque gain and bound of one session (see the module docstring).

    Args:
        stack: the estimator stack whose torque it drives.
        settings: the settings in effect at the start.
        soft_start: whether assistance ramps up (from the first frame and after each restart).

    Attributes:
        settings: the settings in effect (the set gain and bound, the boost setting).
        soft_start: as given.
        ramping: the soft start's ramp is capping the gain or the bound now.
        boost: the intent boost (its ``value`` is the effective boost ``b``).
    """

    def __init__(self, stack: EstimatorStack, settings: SessionSettings, soft_start: bool):
        self._stack = stack
        self.settings = settings
        self.soft_start = soft_start
        self.ramping = soft_start
        self._t0 = 0.0
        self.boost = IntentBoost(stack.names, stack.outputs)

    def soft_start_text(self) -> str | None:
        """What the soft start will do, for the session's log (None: no soft start, or nothing to ramp)."""
        s = self.settings
        ramp = max(s.torque_gain / _GAIN_RATE, s.max_torque_Nm / _BOUND_RATE)
        if not (self.soft_start and ramp > 0):
            return None
        return (f"soft start: assistance ramps up to gain {s.torque_gain:g} and {s.max_torque_Nm:g} N m "
                f"over the first {ramp:.1f} s")  # fmt: skip

    def set(self, settings: SessionSettings, t: float) -> None:
        """The clinician's settings from session time ``t`` on (a running ramp still caps them)."""
        self.settings = settings
        self._stack.retune_torque(settings.torque_gain, settings.max_torque_Nm)
        if self.ramping:
            self._ramp(t)

    def before_step(self, t: float) -> None:
        """The gain and bound the stack runs the sample at session time ``t`` at (the ramp's, while it runs)."""
        if self.ramping:
            self._ramp(t)

    def restart(self, t: float) -> None:
        """The primary restarted at ``t``: with a soft start, assistance ramps up again from 0."""
        if self.soft_start:
            self._t0, self.ramping = t, True
            self._ramp(t)

    def torque(self, t: float, outputs: Sequence[NDArray[np.float64] | None], torque: float) -> float:
        """The torque at the effective gain: the stack's ``torque`` (at the stack's gain) with the intent boost
        of this sample's ``outputs`` applied within the ramp's limits (unchanged while the boost is off)."""
        s = self.settings
        if not self.boost.active(s.intent_gain_boost):  # one comparison while it is off
            return torque
        self.boost.update(t, outputs, s.intent_gain_boost, s.torque_gain)
        headroom, bound = self._limits(t)
        return self.boost.torque(torque, bound, headroom)

    def _limits(self, t: float) -> tuple[float, float]:
        """What the soft start allows the intent boost at session time ``t``: the factor over the stack's torque
        (the ramp's gain over the gain the stack runs at: 1 while the gain itself ramps, then growing at
        0.5/gain per second, so that the boost comes in as a ramp too, never as a step) and the torque bound."""
        s = self.settings
        if not self.soft_start:
            return math.inf, s.max_torque_Nm
        elapsed = max(0.0, t - self._t0)
        ramp_gain = _GAIN_RATE * elapsed
        headroom = max(1.0, ramp_gain / s.torque_gain) if s.torque_gain > 0.0 else math.inf
        return headroom, min(s.max_torque_Nm, _BOUND_RATE * elapsed)

    def _ramp(self, t: float) -> None:
        """Cap gain and bound at their rate limits times the time since the ramp started."""
        s = self.settings
        elapsed = max(0.0, t - self._t0)
        gain = min(s.torque_gain, _GAIN_RATE * elapsed)
        bound = min(s.max_torque_Nm, _BOUND_RATE * elapsed)
        self._stack.retune_torque(gain, bound)
        if gain >= s.torque_gain and bound >= s.max_torque_Nm:
            self.ramping = False


def safe_torque(value: float, bound: float) -> float:
    """``value`` clamped to ``[0, bound]``; 0 when it (or the bound) is not a finite number. Never -0.0 (a zero
    torque times a negative profile, at the soft start's first sample): ``+ 0.0`` makes it +0.0."""
    if not (math.isfinite(value) and math.isfinite(bound)):
        return 0.0
    return min(max(value, 0.0), max(bound, 0.0)) + 0.0

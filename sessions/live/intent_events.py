"""Speed-change intent as session events: one event per detected onset of speeding up or slowing down.

The stack's ``intent`` estimator (seed 001, :class:`estimators.intent_estimator.IntentEstimator`) classifies the
change of the walker's desired speed at each mid-stance, twice per step, and holds its outputs between
mid-stances. Its ``intent_code`` (1 speeding up, -1 slowing down, 0 steady) is therefore a step signal,
and an **onset** (a change to +1 or -1 from 0 or from the opposite sign) is a natural edge that happens
at most twice per step. :class:`IntentOnsets` reports each onset once, at the sample where the code
changed: a walker who keeps speeding up over several steps gives one event, not one per step or per
sample; a return to steady gives none. Events cannot flood: at most one per mid-stance, and in practice
one per speed change.

A failed estimator (outputs None) reports nothing and keeps the last code; an estimator that restarts
(a pause in the stream) holds 0 again, so its next onset is reported.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from gaitscope.sessions import schema
from gaitscope.sessions.live.extensions import Outputs, SessionExtension, SessionHost

__all__ = ["INTENT", "IntentEvents", "IntentOnset", "IntentOnsets"]

#: The registry name of the speed-change intent estimator.
INTENT = "intent"
_OUTPUTS = ("intent_code", "desired_speed_m_s", "intent_m_s", "intent_confidence")


@dataclass(frozen=True)
class IntentOnset:
    """A detected onset: its class (1 speeding up, -1 slowing down), the desired speed after it and the
    change that made it (m/s), and that change in standard deviations of the desired speed."""

    code: int
    desired_m_s: float
    change_m_s: float
    confidence: float

    @property
    def text(self) -> str:
        """``speeding up: desired 1.32 m/s (+0.12 m/s, 2.4 SD)``."""
        word = "speeding up" if self.code > 0 else "slowing down"
        return f"{word}: desired {self.desired_m_s:.2f} m/s ({self.change_m_s:+.2f} m/s, {self.confidence:.1f} SD)"

    @property
    def desired_before_m_s(self) -> float:
        return self.desired_m_s - self.change_m_s


class IntentOnsets:
    """Watches the intent estimator's outputs of a stack, sample by sample (see the module docstring).

    Args:
        names: the stack's estimators, in stack order.
        outputs: each one's output names, in the order it returns them.
    """

    def __init__(self, names: Sequence[str], outputs: Sequence[Sequence[str]]):
        self._k: int | None = None
        self._columns = (0, 0, 0, 0)
        for k, (name, outs) in enumerate(zip(names, outputs, strict=True)):
            if name == INTENT and all(o in outs for o in _OUTPUTS):
                self._k = k
                c, d, i, s = (list(outs).index(o) for o in _OUTPUTS)
                self._columns = (c, d, i, s)
        self._code = 0.0

    @property
    def active(self) -> bool:
        """Whether the stack has the intent estimator."""
        return self._k is not None

    def update(self, outputs: Sequence[NDArray[np.float64] | None]) -> IntentOnset | None:
        """One sample's outputs of every estimator (:attr:`gaitscope.sessions.stack.StackSample.outputs`); the onset
        at it, if there is one. A few comparisons when there is none."""
        k = self._k
        if k is None or k >= len(outputs):
            return None
        y = outputs[k]
        if y is None:
            return None
        c, d, i, s = self._columns
        code = float(y[c])
        if code == self._code:
            return None
        self._code = code
        if code not in (1.0, -1.0):
            return None  # back to steady (or not a class): no event
        return IntentOnset(int(code), float(y[d]), float(y[i]), float(y[s]))


class IntentEvents(SessionExtension):
    """The session extension: each onset an ``intent`` event (field ``desired_speed_m_s``), stored without
    making the sample wait. Only for a stack that runs the intent estimator (:meth:`of`)."""

    def __init__(self, host: SessionHost, onsets: IntentOnsets):
        self.host = host
        self.onsets = onsets

    @classmethod
    def of(cls, host: SessionHost) -> IntentEvents | None:
        onsets = IntentOnsets(host.estimator.stack.names, host.estimator.stack.outputs)
        return cls(host, onsets) if onsets.active else None

    def on_sample(self, state: schema.GaitState, outputs: Outputs) -> None:
        onset = self.onsets.update(outputs)
        if onset is not None:
            before, after = round(onset.desired_before_m_s, 3), round(onset.desired_m_s, 3)
            self.host.event_soon("intent", onset.text, field="desired_speed_m_s", before=before, after=after)

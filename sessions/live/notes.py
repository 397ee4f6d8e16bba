"""The estimator's own events as session events, as a session extension.

The frame estimator (:class:`~gaitscope.sessions.estimation.FrameEstimator`) reports estimator failures and
primary switches (``events``: rare, each estimator fails at most once: each one a system event) and notes
(resynchronisations, restarts, filter faults: merged into at most one system event per
:data:`NOTE_INTERVAL_S` of the session's clock, the next one counting those left out). Both are stored
without making the sample wait, before the sample's other events.
"""

from __future__ import annotations

import math
from typing import Final

from gaitscope.sessions import schema
from gaitscope.sessions.live.extensions import Outputs, SessionExtension, SessionHost

__all__ = ["NOTE_INTERVAL_S", "EstimatorNotes"]

#: Least time between two system events about estimator faults or clock resynchronisations (s).
NOTE_INTERVAL_S: Final = 1.0


class EstimatorNotes(SessionExtension):
    """The estimator's events and notes of one session (see the module docstring)."""

    def __init__(self, runtime: SessionHost):
        self.rt = runtime
        self._last = -math.inf
        self._suppressed = 0

    def on_sample(self, state: schema.GaitState, outputs: Outputs) -> None:
        estimator = self.rt.estimator
        if estimator.events:
            for text in estimator.events:
                self.rt.event_soon("system", text)
            estimator.events.clear()
        notes = estimator.notes
        if not notes:
            return
        now = self.rt.clock()
        if now - self._last < NOTE_INTERVAL_S:
            self._suppressed += len(notes)
        else:
            more = len(notes) - 1 + self._suppressed
            self.rt.event_soon("system", notes[0] + (f" (and {more} more since the last such event)" if more else ""))
            self._last, self._suppressed = now, 0
        notes.clear()

"""One browser's view of a session's stream: a bounded, decimating buffer the runtime never waits on."""

from __future__ import annotations

import asyncio
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from sessions import schema
from sessions.schema import GaitState

#: Samples a subscriber may have waiting before its oldest are dropped (about 5 s at 200 Hz).
SUBSCRIBER_CAPACITY = 1000
#: The estimator outputs a browser gets (those an estimator has): its estimates, to overlay, the online
#: fingerprint (seed 004 GF), which the subject page draws moving, the speed-change intent (seed 001),
#: which the live view's indicator and its desired-vs-actual speed plot read, and the SDRE knee (seed 002),
#: which the live view's hip and knee plot draws. Every output is recorded (``/estimators/<name>``); the
#: primary's are in the gait states already.
STREAMED_OUTPUTS = (
    "phase",
    "phase_rate",
    "stride_length_m",
    "incline_deg",
    "g1",
    "g2",
    "g3",
    "desired_speed_m_s",
    "intent_code",
    "intent_confidence",
    "speed_m_s",
    "knee_sdre_deg",
)
#: Decimals kept of a streamed estimator output (1e-5 of a cycle, m, deg: far below what a plot shows).
STREAMED_DECIMALS = 5


@dataclass(eq=False)
class Subscriber:
    """One browser's view of a session's stream.

    Attributes:
        decimation: every n-th sample is kept.
        layout: the session's estimators and their output names, in stack order (of those outputs, the
            :data:`STREAMED_OUTPUTS` are sent).
        pending: samples not yet sent (bounded; the oldest go first when it is full).
        pending_outputs: each pending sample's estimator outputs (None: failed), row for row.
        dropped: samples lost because the client was too slow.
    """

    decimation: int
    layout: list[tuple[str, tuple[str, ...]]] = field(default_factory=list)
    pending: deque[GaitState] = field(default_factory=lambda: deque(maxlen=SUBSCRIBER_CAPACITY))
    pending_outputs: deque[Sequence[NDArray[np.float64] | None]] = field(
        default_factory=lambda: deque(maxlen=SUBSCRIBER_CAPACITY)
    )
    messages: deque[schema.BaseModel] = field(default_factory=lambda: deque(maxlen=100))
    wake: asyncio.Event = field(default_factory=asyncio.Event)
    dropped: int = 0
    closed: bool = False
    _count: int = 0
    _carry_hs: bool = False

    def offer(self, state: GaitState, outputs: Sequence[NDArray[np.float64] | None] = ()) -> None:
        """A sample (and every estimator's outputs at it, in :attr:`layout` order)."""
        self._count += 1
        if (self._count - 1) % self.decimation:
            self._carry_hs = self._carry_hs or state.heel_strike
            return
        if self._carry_hs and not state.heel_strike:
            state = state.model_copy(update={"heel_strike": True})
        self._carry_hs = False
        if len(self.pending) == self.pending.maxlen:
            self.dropped += 1
        self.pending.append(state)
        self.pending_outputs.append(outputs)
        self.wake.set()

    def batch(self, session_id: int) -> schema.StreamBatch:
        """The pending samples as one message (the compact estimator columns beside the states); empties them."""
        states = list(self.pending)
        rows = list(self.pending_outputs)
        self.pending.clear()
        self.pending_outputs.clear()
        estimators = {}
        for k, (name, outs) in enumerate(self.layout):
            ys = [row[k] if k < len(row) else None for row in rows]
            columns = {
                o: [None if y is None else round(float(y[i]), STREAMED_DECIMALS) for y in ys]
                for i, o in enumerate(outs)
                if o in STREAMED_OUTPUTS
            }
            failed = bool(ys) and ys[-1] is None
            estimators[name] = schema.EstimatorColumns.model_construct(failed=failed, columns=columns)
        return schema.StreamBatch(
            session_id=session_id, states=states, decimation=self.decimation, estimators=estimators
        )

    def close(self) -> None:
        """The session ended: the stream sends what it has, then closes."""
        self.closed = True
        self.wake.set()

    def notify(self, message: schema.BaseModel) -> None:
        self.messages.append(message)
        self.wake.set()

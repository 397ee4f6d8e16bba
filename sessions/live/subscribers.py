"""One browser's view of a session's stream: a bounded, decimating buffer the runtime never waits on."""

from __future__ import annotations

import asyncio
import math
import weakref
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from gaitscope.sessions import schema
from gaitscope.sessions.registry import streamed
from gaitscope.sessions.schema import GaitState

if TYPE_CHECKING:
    from gaitscope.sessions.live.runtime import SessionRuntime

#: Samples a subscriber may have waiting before its oldest are dropped (about 5 s at 200 Hz).
SUBSCRIBER_CAPACITY = 1000
#: Decimals kept of a streamed estimator output (1e-5 of a cycle, m, deg: far below what a plot shows).
STREAMED_DECIMALS = 5


@dataclass(eq=False)
class Subscriber:
    """One browser's view of a session's stream.

    Attributes:
        decimation: every n-th sample is kept.
        layout: the session's estimators and their output names, in stack order (of those outputs, the
            :func:`~gaitscope.sessions.registry.streamed` ones are sent: those its descriptor
            has a gait-state quantity of, plots or shows live; every output is recorded, ``/estimators/<name>``).
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
    _carry_sources: GaitState | None = None  # a skipped sample that said where the estimates come from

    def _kept(self, state: GaitState) -> GaitState | None:
        """``state`` if it is an ``decimation``-th sample (with a heel strike and the estimates' sources of the
        samples skipped since the last kept one carried onto it), else None."""
        self._count += 1
        if (self._count - 1) % self.decimation:
            self._carry_hs = self._carry_hs or state.heel_strike
            if state.sources is not None:
                self._carry_sources = state
            return None
        carry = self._carry_sources
        if carry is not None and state.sources is None:
            state = state.model_copy(update={"sources": carry.sources, "torque_assumes": carry.torque_assumes})
        if self._carry_hs and not state.heel_strike:
            state = state.model_copy(update={"heel_strike": True})
        self._carry_hs, self._carry_sources = False, None
        return state

    def offer(self, state: GaitState, outputs: Sequence[NDArray[np.float64] | None] = ()) -> None:
        """A sample (and every estimator's outputs at it, in :attr:`layout` order)."""
        kept = self._kept(state)
        if kept is None:
            return
        state = kept
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
            shown = streamed(name)
            columns = {
                o: [None if y is None else round(float(y[i]), STREAMED_DECIMALS) for y in ys]
                for i, o in enumerate(outs)
                if o in shown
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


#: Seconds of a session's recent states a newly connected browser gets first, so its plots open full.
HISTORY_S = 30.0
#: The rate the history keeps (Hz): what the live view asks for; a faster source is decimated to it.
HISTORY_RATE_HZ = 60.0
#: States sent per history batch (a 30 s history at 60 Hz is four batches).
HISTORY_BATCH = 500


@dataclass(eq=False)
class SessionHistory(Subscriber):
    """The last :data:`HISTORY_S` seconds (of session time) of a session's states and estimator outputs; its
    first state always says where the estimates come from (``GaitState.sources``), as in force then.

    Fed like a browser's subscriber (every ``decimation``-th sample, heel strikes carried), but never
    sent anything, never counted as a client and never dropping for being slow: the oldest samples leave
    as time passes. Bounded twice: by session time and by ``capacity`` samples.
    """

    seconds: float = HISTORY_S
    capacity: int = int(HISTORY_S * HISTORY_RATE_HZ) + 64

    def __post_init__(self) -> None:
        self.pending = deque(maxlen=self.capacity)
        self.pending_outputs = deque(maxlen=self.capacity)

    def offer(self, state: GaitState, outputs: Sequence[NDArray[np.float64] | None] = ()) -> None:
        """Keeps the sample (every ``decimation``-th) and forgets those older than :attr:`seconds`."""
        if self.pending and state.t < self.pending[-1].t:  # the source restarted (a replay looping)
            self.pending.clear()
            self.pending_outputs.clear()
        kept = self._kept(state)
        if kept is None:
            return
        state = kept
        self.pending.append(state)
        self.pending_outputs.append(outputs)
        oldest = state.t - self.seconds
        while self.pending[0].t < oldest:
            gone = self.pending.popleft()
            self.pending_outputs.popleft()
            if gone.sources is not None and self.pending[0].sources is None:  # the first one says where from
                update = {"sources": gone.sources, "torque_assumes": gone.torque_assumes}
                self.pending[0] = self.pending[0].model_copy(update=update)

    def notify(self, message: schema.BaseModel) -> None:
        """Health and events are not kept: the events come from the store, the health is the present."""

    def close(self) -> None:
        self.closed = True

    def seam(self, sub: Subscriber) -> None:
        """Sets a new subscriber's sample count so that its first sample follows the history's last one by
        its own decimation (no gap, no overlap), with a heel strike skipped meanwhile carried over."""
        since_kept = (self._count - 1) % self.decimation if self._count else 0
        sub._count = (since_kept + 1) % sub.decimation if self._count else 0
        sub._carry_hs = self._carry_hs

    def batches(self, session_id: int, batch: int = HISTORY_BATCH) -> list[schema.StreamBatch]:
        """The kept samples, oldest first, as stream batches of at most ``batch`` states (kept, not emptied)."""
        states = list(self.pending)
        rows = list(self.pending_outputs)
        out = []
        for i in range(0, len(states), batch):
            chunk = Subscriber(decimation=self.decimation, layout=self.layout)
            chunk.pending.extend(states[i : i + batch])
            chunk.pending_outputs.extend(rows[i : i + batch])
            out.append(chunk.batch(session_id))
        return out


#: Each running session's history, attached the first time it is asked for (weakly: it goes with its runtime).
_HISTORIES: weakref.WeakKeyDictionary[SessionRuntime, SessionHistory] = weakref.WeakKeyDictionary()


def attach_history(runtime: SessionRuntime) -> SessionHistory:
    """The session's history, attached to its runtime (fed every sample from now on) if it has none yet.

    The browser stream calls it on connecting; called when a session starts, its history covers the session
    from its first sample.
    """
    history = _HISTORIES.get(runtime)
    if history is None:
        rate = runtime.source.rate_hz or HISTORY_RATE_HZ
        stack = runtime.estimator.stack
        history = SessionHistory(
            decimation=max(1, math.ceil(rate / HISTORY_RATE_HZ)),
            layout=list(zip(stack.names, stack.outputs, strict=True)),
        )
        runtime.subscribers.add(history)
        _HISTORIES[runtime] = history
        stack.announce_sources()  # its first state says where the estimates come from
    return history

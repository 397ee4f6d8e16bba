"""One browser's view of a session's stream: a bounded, decimating buffer the runtime never waits on."""

from __future__ import annotations

import asyncio
from collections import deque
from dataclasses import dataclass, field

from sessions import schema
from sessions.schema import GaitState

#: Samples a subscriber may have waiting before its oldest are dropped (about 5 s at 200 Hz).
SUBSCRIBER_CAPACITY = 1000


@dataclass(eq=False)
class Subscriber:
    """One browser's view of a session's stream.

    Attributes:
        decimation: every n-th sample is kept.
        pending: samples not yet sent (bounded; the oldest go first when it is full).
        dropped: samples lost because the client was too slow.
    """

    decimation: int
    pending: deque[GaitState] = field(default_factory=lambda: deque(maxlen=SUBSCRIBER_CAPACITY))
    messages: deque[schema.BaseModel] = field(default_factory=lambda: deque(maxlen=100))
    wake: asyncio.Event = field(default_factory=asyncio.Event)
    dropped: int = 0
    closed: bool = False
    _count: int = 0
    _carry_hs: bool = False

    def offer(self, state: GaitState) -> None:
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
        self.wake.set()

    def close(self) -> None:
        """The session ended: the stream sends what it has, then closes."""
        self.closed = True
        self.wake.set()

    def notify(self, message: schema.BaseModel) -> None:
        self.messages.append(message)
        self.wake.set()

"""Waiting on a condition, not on the clock: :func:`wait_until` polls a predicate until it holds or a
deadline passes (then fails, saying what it waited for).

The tests drive real servers, sockets and threads, which do their work in their own time: a test waits
for what it needs to see (a sample count, a file, a state), never for a guessed number of seconds. The
poll's short pause is the one sleep of the kind in the tests.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")


def wait_until(predicate: Callable[[], T], timeout: float = 15.0, what: str = "", interval: float = 0.02) -> T:
    """Calls ``predicate`` every ``interval`` s until it returns a true value, and returns that value.

    Raises:
        AssertionError: still false after ``timeout`` seconds (``what`` names the condition).
    """
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        assert time.monotonic() < deadline, f"waited {timeout:g} s for {what or predicate!r}"
        time.sleep(interval)


class ShiftedClock:
    """Monotonic seconds that a test moves ahead: ``time.monotonic()`` plus what :meth:`advance` added.
    Handed to the app as its sessions' clock (``ctx.manager.clock``), it lets a test be past a rate limit's
    window at once, and exactly, where sleeping through it would race it; real time still runs under it."""

    def __init__(self) -> None:
        self.offset = 0.0

    def __call__(self) -> float:
        return time.monotonic() + self.offset

    def advance(self, seconds: float) -> None:
        self.offset += seconds

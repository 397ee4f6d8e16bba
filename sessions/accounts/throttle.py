"""Failed logins slow the guesser down, never lock the account's owner out.

A hard lockout by name (five failures lock the account for 15 minutes) lets anyone lock anyone out, the
admin included: OWASP's Authentication Cheat Sheet ("Account Lockout") names that denial of service and
suggests an exponential lockout instead, and counting failures per account as well as per source so that
guessing from many addresses is slowed too. :class:`LoginThrottle` keeps three counts of failed logins:

- per (address, name): after ``free`` failures, the next attempt of that address at that name waits
  ``base_s`` seconds after the last failure, then twice that after each further failure, up to ``cap_s``;
- per address, whatever the name: the same after ``free_address`` failures (one address trying many names);
- per name, whatever the address: after ``free_account`` failures the account is under attack, and while
  its backoff lasts an address that has failed at that name at least once waits too; **an address that
  has not failed at that name is never kept waiting by the name's count**, so the owner logging in from
  their own machine is not stopped by a stranger's failures. Guessing from many addresses gets one
  guess per address per backoff.

A good login resets its (address, name) and name counts, never the address's (an attacker with one account
of his own could otherwise clear his address). A count is forgotten ``cap_s`` after its last failure once its
wait is over, and each table keeps at most ``max_entries`` (the oldest dropped first), so a flood of invented
names or addresses cannot grow memory without bound.

The throttle never looks at whether a name exists: an unknown name is counted and slowed exactly as a real one,
so its answers do not tell one from the other. Counts live in this process's memory (a restart forgets
them, and several processes on one database count apart); the account's failed-login count the admins see
is kept in the database by :class:`~gaitscope.sessions.accounts.Accounts`. Times are seconds of ``clock`` (monotonic
by default; tests inject one).
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Hashable
from dataclasses import dataclass

__all__ = ["LoginThrottle"]


@dataclass
class _Count:
    failures: int = 0
    last: float = 0.0  # clock time of the last failure


def _failures(count: _Count | None) -> int:
    return 0 if count is None else count.failures


class _Table:
    """Failure counts by key, oldest-touched first, at most ``max_entries``."""

    def __init__(self, max_entries: int) -> None:
        self.max_entries = max_entries
        self.counts: OrderedDict[Hashable, _Count] = OrderedDict()

    def get(self, key: Hashable) -> _Count | None:
        return self.counts.get(key)

    def fail(self, key: Hashable, now: float) -> _Count:
        count = self.counts.pop(key, None) or _Count()
        count.failures += 1
        count.last = now
        self.counts[key] = count  # now the newest
        while len(self.counts) > self.max_entries:
            self.counts.popitem(last=False)
        return count

    def forget(self, key: Hashable) -> None:
        self.counts.pop(key, None)

    def prune(self, stale: Callable[[_Count], bool]) -> None:
        """Drop counts from the oldest on while they are stale."""
        while self.counts:
            key, count = next(iter(self.counts.items()))
            if not stale(count):
                return
            del self.counts[key]


class LoginThrottle:
    """Counts failed logins per (address, name), per address and per name, and says how long an attempt waits.

    Args:
        free: failures of one address at one name before its attempts wait.
        free_address: failures of one address, all names together, before its attempts wait.
        free_account: failures at one name, all addresses together, before the addresses that have failed at
            it wait.
        base_s: the first wait, in seconds; each further failure doubles it.
        cap_s: the longest wait, in seconds; also how long a count is kept after its last failure.
        max_entries: counts kept per table at most.
        clock: seconds, monotonic.

    Thread-safe: the server's threads share one.
    """

    def __init__(
        self,
        *,
        free: int = 5,
        free_address: int = 20,
        free_account: int = 20,
        base_s: float = 1.0,
        cap_s: float = 900.0,
        max_entries: int = 100_000,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if min(free, free_address, free_account, max_entries) < 1 or base_s <= 0 or cap_s < base_s:
            raise ValueError("free counts and max_entries must be at least 1, and 0 < base_s <= cap_s")
        self.free, self.free_address, self.free_account = free, free_address, free_account
        self.base_s, self.cap_s = base_s, cap_s
        self._clock = clock
        self._lock = threading.Lock()
        self._pairs = _Table(max_entries)
        self._addresses = _Table(max_entries)
        self._names = _Table(max_entries)

    def _until(self, count: _Count | None, free: int) -> float:
        """Clock time before which the next attempt waits (0: none)."""
        if count is None or count.failures < free:
            return 0.0
        return count.last + min(self.base_s * 2.0 ** (count.failures - free), self.cap_s)

    def wait(self, address: str, name: str) -> float:
        """Seconds the attempt of ``address`` at ``name`` must still wait; 0: it may be checked now."""
        with self._lock:
            now = self._clock()
            self._prune(now)
            pair = self._pairs.get((address, name))
            until = max(self._until(pair, self.free), self._until(self._addresses.get(address), self.free_address))
            if pair is not None:  # only an address that has failed at this name waits for the name's count
                until = max(until, self._until(self._names.get(name), self.free_account))
            return max(0.0, until - now)

    def tries_left(self, address: str, name: str) -> int:
        """Failed logins ``address`` may still make at ``name`` before its attempts wait (0: the next one waits
        or would), the least of the three counts' (the name's once this address has failed at it). It never
        looks at whether the name exists, so telling it tells nothing of that."""
        with self._lock:
            now = self._clock()
            self._prune(now)
            pair = self._pairs.get((address, name))
            left = [self.free - _failures(pair), self.free_address - _failures(self._addresses.get(address))]
            if pair is not None:
                left.append(self.free_account - _failures(self._names.get(name)))
            return max(0, min(left))

    def name_wait(self, name: str) -> float:
        """Seconds the addresses that have failed at ``name`` still wait for the name's count (0: none)."""
        with self._lock:
            now = self._clock()
            return max(0.0, self._until(self._names.get(name), self.free_account) - now)

    def failed(self, address: str, name: str) -> None:
        """Count a failed login of ``address`` at ``name``."""
        with self._lock:
            now = self._clock()
            self._pairs.fail((address, name), now)
            self._addresses.fail(address, now)
            self._names.fail(name, now)

    def succeeded(self, address: str, name: str) -> None:
        """A good login: the (address, name) and the name's counts start again; the address's stays."""
        with self._lock:
            self._pairs.forget((address, name))
            self._names.forget(name)

    def forget_name(self, name: str) -> None:
        """The name's count starts again (the database says the account was unlocked or logged in)."""
        with self._lock:
            self._names.forget(name)

    def unlock(self, name: str) -> None:
        """An admin's unlock: the name's count and every address's count at that name start again."""
        with self._lock:
            self._names.forget(name)
            for key in [k for k in self._pairs.counts if isinstance(k, tuple) and k[1] == name]:
                self._pairs.forget(key)

    def _prune(self, now: float) -> None:
        def stale(count: _Count) -> bool:
            return now - count.last > self.cap_s

        for table in (self._pairs, self._addresses, self._names):
            table.prune(stale)

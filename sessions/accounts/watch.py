"""Who to tell when a login ends: the open sockets of each login session.

A browser's websocket is allowed once, when it opens; the login it was opened with may end while it streams
(logout, the account disabled or demoted, a password changed or reset). Each socket registers a callback under
its login's id with :meth:`LoginWatch.watch`; :class:`~sessions.accounts.Accounts` calls :meth:`LoginWatch.end`
with the ids of the logins it has just ended (after the commit), which calls every callback of those logins
at once: the socket closes within moments, not at its next poll. A callback is called from whatever thread
ended the login, so it must only hand the close to the socket's own event loop (``call_soon_threadsafe``).

Logins ended by another process on the same database (``gaitscope user reset-password``) or by their expiry are
not seen here: a socket asks the database about its login now and then too
(:meth:`~gaitscope.sessions.accounts.Accounts.open_logins`). :meth:`LoginWatch.open_ids` lists the watched logins.
"""

from __future__ import annotations

import itertools
import logging
import threading
from collections.abc import Callable, Iterable

__all__ = ["LoginWatch"]

log = logging.getLogger("gaitscope")

#: A socket's callback: told the reason, it closes the socket (without waiting for it).
OnEnd = Callable[[str], None]


class LoginWatch:
    """Callbacks of open sockets by login id. Thread-safe."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._watchers: dict[int, dict[int, OnEnd]] = {}
        self._keys = itertools.count()

    def watch(self, login_id: int, on_end: OnEnd) -> Callable[[], None]:
        """Call ``on_end(reason)`` when login ``login_id`` ends; returns the function that stops watching
        (call it when the socket closes for any other reason)."""
        key = next(self._keys)
        with self._lock:
            self._watchers.setdefault(login_id, {})[key] = on_end

        def unwatch() -> None:
            with self._lock:
                watchers = self._watchers.get(login_id)
                if watchers is not None:
                    watchers.pop(key, None)
                    if not watchers:
                        del self._watchers[login_id]

        return unwatch

    def end(self, login_ids: Iterable[int], reason: str) -> int:
        """Logins ``login_ids`` have ended: call (and forget) their sockets' callbacks. Returns how many."""
        with self._lock:
            called = [cb for i in set(login_ids) for cb in self._watchers.pop(i, {}).values()]
        for on_end in called:
            try:
                on_end(reason)
            except Exception:  # one socket's failure to close must not keep the others open
                log.exception("closing a socket of an ended login failed")
        return len(called)

    def open_ids(self) -> list[int]:
        """The logins with a watched socket."""
        with self._lock:
            return list(self._watchers)

"""One writer thread for the database writes of the server's event loop.

A database write blocks: SQLite commits with an ``fsync`` of its write-ahead log, which takes under a
millisecond on a quiet disk and hundreds on a busy one (the recordings' own fsyncs measured up to 490 ms,
see :mod:`gaitscope.sessions.formats.recording`), and a write waits for the database's write lock as long as another
writer holds it. On the event loop such a wait stalls every session's samples at once. So the writes that
the loop's code makes (a session's events, its trial rows, the audit entries of async routes) go to
:class:`StoreWriter`: one thread that owns them and makes them one at a time, in the order they were
submitted.

- :meth:`StoreWriter.submit` queues a write and returns at once with its :class:`Write`; from the event
  loop the write's :attr:`Write.future` is settled on the loop (``loop.call_soon_threadsafe``), futures in
  the order of their writes. ``await writer.run(fn)`` is the same for a coroutine that must wait for the
  result (what is stored first and applied only then); :meth:`StoreWriter.call` waits for it in the
  calling thread.
- A write that fails is logged (with what it was) and its future raises the error; it is never dropped in
  silence, and the writes after it go on.
- :meth:`StoreWriter.close` refuses new writes, makes every write already queued, then ends the thread.

A write is a callable that takes no argument (``functools.partial(store.add_event, ...)``): the writer knows
nothing of the database, and a test can give it any function.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import queue
import threading
from collections.abc import Callable
from typing import Any, Final, Generic, TypeVar

__all__ = ["StoreWriter", "Write", "WriterClosed"]

log = logging.getLogger("gaitscope")

T = TypeVar("T")

_STOP: Final = object()


class WriterClosed(RuntimeError):
    """A write submitted after :meth:`StoreWriter.close`: not made."""


class Write(Generic[T]):
    """One queued write: what it is (for the log), and its outcome once made.

    :attr:`future` is an asyncio future of the loop it was submitted from (None when submitted from a thread
    with no running loop); :meth:`result` waits for the outcome in any thread.
    """

    def __init__(self, fn: Callable[[], T], what: str, loop: asyncio.AbstractEventLoop | None) -> None:
        self.fn = fn
        self.what = what
        self.loop = loop
        self.future: asyncio.Future[T] | None = None if loop is None else loop.create_future()
        self._done = threading.Event()
        self._value: T | None = None
        self._error: BaseException | None = None

    def done(self) -> bool:
        """Whether the write has been made (or has failed)."""
        return self._done.is_set()

    def result(self, timeout: float | None = None) -> T:
        """Wait for the write (at most ``timeout`` s) and return what it returned; raise what it raised.

        Raises:
            TimeoutError: not made within ``timeout``.
        """
        if not self._done.wait(timeout):
            raise TimeoutError(f"{self.what}: not written within {timeout} s")
        if self._error is not None:
            raise self._error
        return self._value  # type: ignore[return-value]

    def _run(self) -> None:
        try:
            self._value = self.fn()
        except BaseException as e:  # reported to the caller, never dropped; the writer goes on
            log.error("database write failed (%s): %s", self.what, e)
            self._error = e
        self._done.set()
        if self.loop is not None:
            with contextlib.suppress(RuntimeError):  # the loop has closed: nobody is waiting there
                self.loop.call_soon_threadsafe(self._settle)

    def _settle(self) -> None:
        future = self.future
        if future is None or future.done():  # cancelled by its caller
            return
        if self._error is not None:
            future.set_exception(self._error)
            future.exception()  # logged above already: no "exception never retrieved" when nobody awaits it
        else:
            future.set_result(self._value)  # type: ignore[arg-type]


class StoreWriter:
    """The thread that makes the event loop's database writes, one at a time, in submission order.

    Args:
        name: the thread's name.
    """

    def __init__(self, name: str = "gaitscope-writer") -> None:
        self._queue: queue.SimpleQueue[Write[Any] | object] = queue.SimpleQueue()
        self._closed = False
        self._submit_lock = threading.Lock()  # a write is queued before close's stop, or refused
        self._thread = threading.Thread(target=self._work, name=name, daemon=True)
        self._thread.start()

    @property
    def closed(self) -> bool:
        return self._closed

    def submit(self, fn: Callable[[], T], what: str) -> Write[T]:
        """Queue ``fn`` (a write, described by ``what`` for the log) and return its :class:`Write` at once.

        Raises:
            WriterClosed: the writer was closed; nothing was queued.
        """
        try:
            loop: asyncio.AbstractEventLoop | None = asyncio.get_running_loop()
        except RuntimeError:
            loop = None
        write = Write(fn, what, loop)
        with self._submit_lock:
            if self._closed:
                raise WriterClosed(f"{what}: the database writer is closed (the server is stopping)")
            self._queue.put(write)
        return write

    async def run(self, fn: Callable[[], T], what: str) -> T:
        """Queue ``fn`` and wait (without blocking the loop) for what it returns; raise what it raised."""
        future = self.submit(fn, what).future
        assert future is not None  # submitted from this running loop
        return await future

    def call(self, fn: Callable[[], T], what: str, timeout: float | None = None) -> T:
        """Queue ``fn`` and wait in this thread for what it returns (after every write queued before it)."""
        return self.submit(fn, what).result(timeout)

    def flush(self, timeout: float | None = None) -> None:
        """Wait in this thread until every write queued so far has been made."""
        self.call(lambda: None, "flush", timeout)

    def close(self, timeout: float | None = None) -> None:
        """Refuse new writes, make every write already queued, and end the thread; idempotent."""
        with self._submit_lock:
            if not self._closed:
                self._closed = True
                self._queue.put(_STOP)
        if threading.current_thread() is not self._thread:
            self._thread.join(timeout)

    def _work(self) -> None:
        while True:
            write = self._queue.get()
            if write is _STOP:
                return
            assert isinstance(write, Write)
            write._run()

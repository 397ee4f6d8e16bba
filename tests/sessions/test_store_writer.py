"""The database writer: the event loop's writes made off the loop, one at a time, in submission order; a
failure reported to its caller and logged, never dropped; every queued write made before close returns."""

from __future__ import annotations

import asyncio
import functools
import logging
import threading
import time
from collections.abc import Iterator

import pytest

from gaitscope.sessions import schema
from gaitscope.sessions.store import NotFound, Store
from gaitscope.sessions.store_writer import StoreWriter, WriterClosed


@pytest.fixture
def store(database_url: str) -> Iterator[Store]:
    s = Store(database_url)
    yield s
    s.close()


def _session(store: Store) -> int:
    subject = store.create_subject(schema.SubjectCreate(code="W01", leg_length_m=0.9, mass_kg=70))
    return store.create_session(schema.SessionCreate(subject_id=subject.id, source=schema.DeviceSource())).id


def _add(store: Store, session_id: int, text: str) -> functools.partial[schema.Event]:
    return functools.partial(store.add_event, session_id, t=0.0, kind="system", text=text)


def test_writes_are_made_off_the_loop_in_order_and_settle_on_the_loop_in_order(store: Store) -> None:
    sid = _session(store)
    writer = StoreWriter()
    gate = threading.Event()

    async def main() -> tuple[list[str], list[str], float]:
        loop_thread = threading.get_ident()
        threads: list[int] = []

        def held() -> None:
            threads.append(threading.get_ident())
            gate.wait(10)

        writer.submit(held, "a write that waits")
        t0 = time.perf_counter()
        writes = [writer.submit(_add(store, sid, f"e{i}"), f"event {i}") for i in range(50)]
        submitted_s = time.perf_counter() - t0  # the loop did not wait for the held write
        settled: list[str] = []
        for w in writes:
            assert w.future is not None
            w.future.add_done_callback(lambda f: settled.append(f.result().text))
        assert store.list_events(sid) == [] and not any(w.done() for w in writes)
        gate.set()
        events = await asyncio.gather(*(w.future for w in writes if w.future is not None))
        assert threads and threads[0] != loop_thread
        return [e.text for e in events], settled, submitted_s

    try:
        texts, settled, submitted_s = asyncio.run(main())
    finally:
        writer.close()
    expected = [f"e{i}" for i in range(50)]
    assert texts == settled == expected
    assert [e.text for e in store.list_events(sid)] == expected
    ids = [e.id for e in store.list_events(sid)]
    assert ids == sorted(ids)
    assert submitted_s < 0.5


def test_a_failed_write_is_logged_and_raised_to_its_caller_and_the_next_ones_go_on(
    store: Store, caplog: pytest.LogCaptureFixture
) -> None:
    sid = _session(store)
    writer = StoreWriter()

    async def main() -> tuple[BaseException | None, schema.Event]:
        bad = writer.submit(_add(store, sid + 1000, "to nowhere"), "event of a session that does not exist")
        good = writer.submit(_add(store, sid, "after it"), "event after the failure")
        assert bad.future is not None and good.future is not None
        with pytest.raises(NotFound, match=f"session {sid + 1000} does not exist"):
            await bad.future
        return bad.future.exception(), await good.future

    with caplog.at_level(logging.ERROR, logger="gaitscope"):
        error, event = asyncio.run(main())
    writer.close()
    assert isinstance(error, NotFound)
    assert event.text == "after it" and [e.text for e in store.list_events(sid)] == ["after it"]
    assert any(
        "database write failed (event of a session that does not exist)" in r.getMessage() for r in caplog.records
    )
    # a thread with no loop gets the same answer from call()
    other = StoreWriter()
    with pytest.raises(NotFound):
        other.call(_add(store, sid + 1000, "again"), "again")
    assert other.call(_add(store, sid, "from a thread"), "from a thread").text == "from a thread"
    other.close()


def test_close_makes_every_queued_write_then_refuses_more(store: Store) -> None:
    sid = _session(store)
    writer = StoreWriter()
    gate = threading.Event()
    writer.submit(lambda: gate.wait(10), "held")
    writes = [writer.submit(_add(store, sid, f"q{i}"), f"queued {i}") for i in range(20)]
    threading.Timer(0.2, gate.set).start()
    writer.close()  # returns once the queue is drained
    assert all(w.done() for w in writes)
    assert [e.text for e in store.list_events(sid)] == [f"q{i}" for i in range(20)]
    with pytest.raises(WriterClosed, match="the database writer is closed"):
        writer.submit(_add(store, sid, "late"), "late")
    writer.close()  # idempotent
    assert [e.text for e in store.list_events(sid)][-1] == "q19"

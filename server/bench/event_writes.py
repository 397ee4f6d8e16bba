"""``python -m gaitscope.server.bench.event_writes``: what one session event costs the event loop, stored on the loop
(as before the database writer) and submitted to the writer (:mod:`gaitscope.sessions.store_writer`, as now).

A fresh SQLite database in a temporary folder (on the disk of ``--dir``, the data folder's disk to measure
that one); ``--events`` events of each kind alternately, 10 ms apart, from a running asyncio loop. Prints
the loop's time per event (median, p95, max) for both, and checks that every event was stored.
"""

from __future__ import annotations

import argparse
import asyncio
import functools
import tempfile
import time

import numpy as np

from gaitscope.sessions import schema
from gaitscope.sessions.store import Store
from gaitscope.sessions.store_writer import StoreWriter


async def _measure(store: Store, writer: StoreWriter, session_id: int, events: int) -> dict[str, list[float]]:
    times: dict[str, list[float]] = {"on the loop (before)": [], "submitted to the writer (now)": []}
    for i in range(events):
        add = functools.partial(store.add_event, session_id, t=i * 0.1, kind="intent", text="speeding up")
        t0 = time.perf_counter()
        add()
        times["on the loop (before)"].append(time.perf_counter() - t0)
        await asyncio.sleep(0.01)
        t0 = time.perf_counter()
        writer.submit(add, f"event {i}")
        times["submitted to the writer (now)"].append(time.perf_counter() - t0)
        await asyncio.sleep(0.01)
    await asyncio.to_thread(writer.flush)
    return times


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--events", type=int, default=200, help="events of each kind (default 200)")
    parser.add_argument("--dir", default=None, help="where the temporary database goes (default: the temp folder)")
    a = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(dir=a.dir) as d:
        store = Store(f"sqlite:///{d}/bench.db")
        subject = store.create_subject(schema.SubjectCreate(code="BENCH", leg_length_m=0.9, mass_kg=70))
        session = store.create_session(schema.SessionCreate(subject_id=subject.id, source=schema.DeviceSource()))
        writer = StoreWriter()
        try:
            times = asyncio.run(_measure(store, writer, session.id, a.events))
        finally:
            writer.close()
        stored = len(store.list_events(session.id))
        store.close()
    for name, values in times.items():
        ms = np.asarray(values) * 1e3
        print(
            f"loop time per event, {name}: median {np.median(ms):.3f} ms, p95 {np.percentile(ms, 95):.3f} ms, "
            f"max {ms.max():.2f} ms"
        )
    print(f"{stored} of {2 * a.events} events stored")
    return 0 if stored == 2 * a.events else 1


if __name__ == "__main__":
    raise SystemExit(main())

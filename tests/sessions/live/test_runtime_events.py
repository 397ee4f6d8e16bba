"""A session's events and the database writer: the sample path's events (here intent onsets) never make a sample
wait for the database, and are stored, sent to the browsers and recorded in the order they happened; a change
of settings is still stored before it is applied."""

from __future__ import annotations

import asyncio
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import pytest
from fastapi.testclient import TestClient

from gaitscope.sessions import schema
from gaitscope.sessions.formats.mcap_io import read_events
from gaitscope.sessions.live.runtime import ChangeNotSaved, SessionRuntime, SettingRejected
from gaitscope.sessions.live.sources import LiveDevice, frames_from_table
from gaitscope.sessions.store_writer import StoreWriter
from gaitscope.sessions.synth.trials import sensor_trial


def _runtime(
    client: TestClient, writer: StoreWriter, code: str = "RE01", clock: Callable[[], float] = time.monotonic
) -> SessionRuntime:
    ctx = client.app.state.ctx  # type: ignore[attr-defined]
    r = client.post("/api/subjects", json={"code": code, "leg_length_m": 0.9, "mass_kg": 70})
    body = {
        "subject_id": r.json()["id"],
        "source": {"kind": "device"},
        "settings": {"estimators": ["phase_ekf", "intent"]},
        "start": False,
    }
    session = ctx.store.get_session(client.post("/api/sessions", json=body).json()["id"])
    model, _ = ctx.models.get(session.settings.model)
    subject = ctx.store.get_subject(session.subject_id)
    data_dir = ctx.settings.data_dir
    return SessionRuntime(session, subject, model, LiveDevice(), ctx.store, data_dir, writer=writer, clock=clock)


def test_the_rate_limits_of_settings_changes_read_the_injected_clock(client: TestClient) -> None:
    """A step of 1 in the measurement-noise scale (5/s) needs 0.2 s before the next: the session's clock says when,
    not the machine's. (Lowering the torque is never held back: the torque settings' rates hold back raises.)"""
    now = [100.0]
    writer = StoreWriter()
    try:
        runtime = _runtime(client, writer, "RE04", clock=lambda: now[0])
        runtime.change_settings(schema.SettingsChange(measurement_noise_scale=2.0, actor="ann"))
        now[0] += 0.19
        with pytest.raises(SettingRejected, match=r"measurement_noise_scale changed 0\.19 s ago.*try again in 0\.01 s"):
            runtime.change_settings(schema.SettingsChange(measurement_noise_scale=3.0, actor="ann"))
        assert runtime.settings.measurement_noise_scale == 2.0
        now[0] += 0.02
        changed = runtime.change_settings(schema.SettingsChange(measurement_noise_scale=3.0, actor="ann"))
        assert changed.settings.measurement_noise_scale == 3.0
    finally:
        writer.close()


def test_intent_events_wait_for_no_database_write_and_are_stored_sent_and_recorded_in_order(
    client: TestClient,
) -> None:
    ctx = client.app.state.ctx  # type: ignore[attr-defined]
    writer = StoreWriter()
    gate = threading.Event()
    sensors, _, _ = sensor_trial([(1.0, 0.0, 6), (1.3, 0.0, 6), (0.9, 0.0, 6)], rate_hz=100.0)

    async def main() -> None:
        runtime = _runtime(client, writer)
        sid = runtime.session.id
        sub = runtime.subscribe(0.0)
        trial = runtime.start_recording("walk")
        writer.submit(lambda: gate.wait(20), "a slow database")  # every write after it waits
        t0 = time.monotonic()
        for frame in frames_from_table(sensors):
            runtime.process(frame, time.time_ns())
        walked_s = time.monotonic() - t0
        # the samples went on while the database held every write back
        assert walked_s < 15, walked_s
        assert [e for e in ctx.store.list_events(sid) if e.kind == "intent"] == []
        assert not any(isinstance(m, schema.EventMessage) and m.event.kind == "intent" for m in sub.messages)
        gate.set()
        await asyncio.to_thread(writer.flush)
        await asyncio.sleep(0)  # the loop runs the writes' callbacks
        stored = [e for e in ctx.store.list_events(sid) if e.kind == "intent"]
        sent = [m.event for m in sub.messages if isinstance(m, schema.EventMessage) and m.event.kind == "intent"]
        assert len(stored) >= 2  # sped up, then slowed down
        assert sent == stored
        assert [e.id for e in stored] == sorted(e.id for e in stored)
        assert [e.t for e in stored] == sorted(e.t for e in stored)
        assert [e for e in ctx.store.trial_events(trial.id) if e.kind == "intent"] == stored
        runtime.stop_recording()
        recorded = [e for e in read_events(ctx.settings.data_dir / trial.path) if e["kind"] == "intent"]
        assert [int(e["id"]) for e in recorded] == [e.id for e in stored]
        await runtime.stop()

    try:
        asyncio.run(main())
    finally:
        writer.close()


def test_a_settings_change_is_stored_before_it_is_applied_and_after_the_events_before_it(client: TestClient) -> None:
    writer = StoreWriter()
    now = [0.0]
    runtime = _runtime(client, writer, clock=lambda: now[0])
    ctx = client.app.state.ctx  # type: ignore[attr-defined]
    sid = runtime.session.id
    gate = threading.Event()
    writer.submit(lambda: gate.wait(20), "a slow write queued first")
    with ThreadPoolExecutor(1) as route:  # a sync route's thread, waiting for the writer
        changing = route.submit(runtime.change_settings, schema.SettingsChange(torque_gain=0.9, actor="ann"))
        assert runtime.settings.torque_gain == 1.0 == ctx.store.get_session(sid).settings.torque_gain
        gate.set()
        session = changing.result(20)
    assert session.settings.torque_gain == 0.9 == ctx.store.get_session(sid).settings.torque_gain
    assert runtime.estimator.settings.torque_gain == 0.9
    # a database that refuses the write: nothing applied
    writer.close()
    now[0] += 0.2  # past the rate limit of a 0.1 step
    try:
        runtime.change_settings(schema.SettingsChange(torque_gain=1.0, actor="ann", confirm=True))
    except ChangeNotSaved as e:
        assert "could not be saved" in str(e)
    else:
        raise AssertionError("a change the writer could not store was applied")
    assert runtime.settings.torque_gain == 0.9 == ctx.store.get_session(sid).settings.torque_gain


def test_an_awaited_settings_change_holds_its_session_until_applied_and_no_other(client: TestClient) -> None:
    """The settings route awaits the writer: the loop and the other sessions go on; the session changed waits
    (``SettingsChanges.applied``), so the change applies at the sample its event names."""
    writer = StoreWriter()
    gate = threading.Event()
    sensors, _, _ = sensor_trial([(1.0, 0.0, 3)], rate_hz=100.0)
    frames = list(frames_from_table(sensors))

    async def main() -> None:
        ctx = client.app.state.ctx  # type: ignore[attr-defined]
        changed, other = _runtime(client, writer, "RE02"), _runtime(client, writer, "RE03")
        for frame in frames[:50]:
            changed.process(frame, time.time_ns())
        writer.submit(lambda: gate.wait(20), "a slow database")
        change = asyncio.create_task(changed.change_settings_async(schema.SettingsChange(torque_gain=0.9, actor="a")))
        await asyncio.sleep(0)
        held = asyncio.create_task(changed.settings_changes.applied())
        for frame in frames[:100]:  # the loop is free: another session's samples go on
            other.process(frame, time.time_ns())
            await asyncio.sleep(0)
        assert not held.done() and not change.done()
        assert changed.estimator.settings.torque_gain == 1.0
        with pytest.raises(SettingRejected, match="another settings change is being saved"):
            changed.change_settings(schema.SettingsChange(torque_gain=0.8, actor="b"))
        gate.set()
        session = await change
        await asyncio.wait_for(held, 5)
        assert session.settings.torque_gain == 0.9 == changed.estimator.settings.torque_gain
        assert ctx.store.get_session(session.id).settings.torque_gain == 0.9
        event = [e for e in ctx.store.list_events(session.id) if e.kind == "setting"][-1]
        assert event.t == changed.last_t  # no sample of this session ran between the change's time and its effect
        await changed.stop()
        await other.stop()

    try:
        asyncio.run(main())
    finally:
        writer.close()

"""The database layer: round trips, errors, ordering, time stamps, persistence and concurrent writes."""

from __future__ import annotations

import contextlib
import datetime as dt
import sqlite3
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from pydantic import ValidationError
from sqlalchemy import text
from sqlalchemy.exc import IntegrityError

from gaitscope.sessions import schema
from gaitscope.sessions import store as store_module
from gaitscope.sessions.store import Conflict, NotFound, Store

T0 = dt.datetime(2024, 5, 1, 12, 0, 0, tzinfo=dt.UTC)


class Clock:
    """Stands in for the store's clock: a fixed time moved on by hand."""

    def __init__(self) -> None:
        self.now = T0

    def __call__(self) -> dt.datetime:
        return self.now

    def advance(self, seconds: float) -> None:
        self.now += dt.timedelta(seconds=seconds)


@pytest.fixture
def clock(monkeypatch: pytest.MonkeyPatch) -> Clock:
    c = Clock()
    monkeypatch.setattr(store_module, "_now", c)
    return c


def _url(path: Path) -> str:
    return f"sqlite:///{path}"


@pytest.fixture
def store(database_url: str, clock: Clock) -> Iterator[Store]:
    s = Store(database_url)  # SQLite, or PostgreSQL when the suite runs against one (tests/conftest.py)
    yield s
    s.close()


def _subject(store: Store, code: str = "AB01", **fields: Any) -> schema.Subject:
    body = {"leg_length_m": 0.92, "mass_kg": 71.5, **fields}
    return store.create_subject(schema.SubjectCreate(code=code, **body))


def _session(store: Store, subject_id: int, **fields: Any) -> schema.Session:
    return store.create_session(schema.SessionCreate(subject_id=subject_id, **fields))


# --- subjects ------------------------------------------------------------------------------------


def test_subject_round_trip(store: Store) -> None:
    created = _subject(store, "AB01", side="left", notes="right knee brace")
    assert created == schema.Subject(
        id=1,
        code="AB01",
        leg_length_m=0.92,
        mass_kg=71.5,
        side="left",
        notes="right knee brace",
        created_utc="2024-05-01T12:00:00+00:00",
    )
    assert store.get_subject(1) == created
    assert store.list_subjects() == [created]


def test_duplicate_code_is_a_conflict_and_changes_nothing(store: Store) -> None:
    a = _subject(store, "AB01")
    b = _subject(store, "AB02")
    with pytest.raises(Conflict, match=r"^subject code 'AB01' exists$"):
        _subject(store, "AB01", mass_kg=90.0)
    assert store.list_subjects() == [a, b]
    assert _subject(store, "AB03").id == 3  # the failed insert left no row and no gap behind


def test_subjects_are_listed_in_creation_order(store: Store) -> None:
    codes = ["ZZ9", "AB01", "m.x-1"]
    for code in codes:
        _subject(store, code)
    assert [s.code for s in store.list_subjects()] == codes
    assert [s.id for s in store.list_subjects()] == [1, 2, 3]


# --- unknown ids ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda s: s.get_subject(9), "subject 9 does not exist"),
        (lambda s: s.get_session(7), "session 7 does not exist"),
        (lambda s: s.set_session_state(7, "running"), "session 7 does not exist"),
        (lambda s: s.set_session_settings(7, schema.SessionSettings()), "session 7 does not exist"),
        (lambda s: s.create_trial(7, "walk", "recordings/x.mcap"), "session 7 does not exist"),
        (lambda s: s.get_trial(5), "trial 5 does not exist"),
        (lambda s: s.finish_trial(5, "finished", 10, 0.05), "trial 5 does not exist"),
        (lambda s: s.add_event(7, t=0.0, kind="system", text="x"), "session 7 does not exist"),
        (lambda s: s.add_event(1, t=0.0, kind="system", text="x", trial_id=5), "trial 5 does not exist"),
        (lambda s: s.list_events(7), "session 7 does not exist"),
        (lambda s: s.trial_events(5), "trial 5 does not exist"),
    ],
)
def test_unknown_ids_are_not_found(store: Store, call: Callable[[Store], object], message: str) -> None:
    _session(store, _subject(store).id)  # session 1 exists, so only the named id is missing
    with pytest.raises(NotFound, match=f"^{message}$"):
        call(store)


def test_session_for_a_missing_subject_is_not_found_and_not_stored(store: Store) -> None:
    with pytest.raises(NotFound, match=r"^subject 4 does not exist$"):
        _session(store, 4)
    assert store.list_sessions() == []


def test_the_database_enforces_foreign_keys(store: Store) -> None:
    # Below the store's own checks: the database itself refuses a row pointing at no session.
    with store._engine.begin() as conn, pytest.raises(IntegrityError, match=r"(?i)foreign key"):
        conn.execute(
            text(
                "INSERT INTO events (session_id, t, wall_utc, kind, text, actor) "
                "VALUES (99, 0.0, 'x', 'system', 'x', 'system')"
            )
        )


# --- sessions ------------------------------------------------------------------------------------


def test_session_round_trip_with_every_source(store: Store) -> None:
    subject = _subject(store)
    settings = schema.SessionSettings(torque_gain=0.4, max_torque_Nm=12.5, model="cohort-b")
    replay = schema.ReplaySource(trial_id=3, speed=4.0, loop=True)
    protocol = [schema.ProtocolStep(speed_m_s=0.9, incline_deg=-2.5, strides=12)]
    simulated = schema.SimulatedSource(protocol=protocol, rate_hz=100.0, cohort_subject=4, seed=11)
    upload = schema.UploadSource(filename="walk.mcap")
    sources: list[schema.SourceSpec] = [simulated, replay, schema.DeviceSource(), upload]
    for i, source in enumerate(sources, start=1):
        created = _session(store, subject.id, source=source, settings=settings)
        assert created == schema.Session(
            id=i,
            subject_id=subject.id,
            source=source,
            settings=settings,
            state="created",
            created_utc="2024-05-01T12:00:00+00:00",
        )
        assert store.get_session(i) == created
        assert type(store.get_session(i).source) is type(source)


def test_session_defaults(store: Store) -> None:
    created = _session(store, _subject(store).id)
    assert created.source == schema.SimulatedSource()
    assert created.settings == schema.SessionSettings()
    assert (created.started_utc, created.stopped_utc) == (None, None)


def test_sessions_are_listed_newest_first_and_by_subject(store: Store) -> None:
    a, b = _subject(store, "A1").id, _subject(store, "B1").id
    for subject_id in (a, b, a, b, a):
        _session(store, subject_id)
    assert [s.id for s in store.list_sessions()] == [5, 4, 3, 2, 1]
    assert [s.id for s in store.list_sessions(subject_id=a)] == [5, 3, 1]
    assert [s.id for s in store.list_sessions(subject_id=b)] == [4, 2]
    assert store.list_sessions(subject_id=99) == []


def test_session_state_stamps_its_first_start_and_stop(store: Store, clock: Clock) -> None:
    session_id = _session(store, _subject(store).id).id
    clock.advance(5)
    running = store.set_session_state(session_id, "running")
    assert (running.state, running.started_utc, running.stopped_utc) == (
        "running",
        "2024-05-01T12:00:05+00:00",
        None,
    )
    clock.advance(60)
    assert store.set_session_state(session_id, "running").started_utc == "2024-05-01T12:00:05+00:00"
    clock.advance(0.9)  # stamps are to the second
    stopped = store.set_session_state(session_id, "stopped")
    assert (stopped.state, stopped.started_utc, stopped.stopped_utc) == (
        "stopped",
        "2024-05-01T12:00:05+00:00",
        "2024-05-01T12:01:05+00:00",
    )
    clock.advance(10)
    assert store.set_session_state(session_id, "stopped").stopped_utc == "2024-05-01T12:01:05+00:00"
    assert store.get_session(session_id) == stopped
    assert stopped.created_utc == "2024-05-01T12:00:00+00:00"


def test_set_session_settings(store: Store) -> None:
    session_id = _session(store, _subject(store).id).id
    settings = schema.SessionSettings(torque_gain=1.75, process_noise_scale=0.25)
    assert store.set_session_settings(session_id, settings).settings == settings
    assert store.get_session(session_id).settings == settings


def test_running_sessions(store: Store) -> None:
    subject_id = _subject(store).id
    ids = [_session(store, subject_id).id for _ in range(4)]
    for i in (ids[2], ids[0], ids[3]):
        store.set_session_state(i, "running")
    store.set_session_state(ids[3], "stopped")
    assert [s.id for s in store.running_sessions()] == [ids[0], ids[2]]


def test_a_value_the_schema_refuses_is_rolled_back(store: Store) -> None:
    session_id = _session(store, _subject(store).id).id
    with pytest.raises(ValidationError):
        store.set_session_state(session_id, "paused")  # type: ignore[arg-type]
    assert store.get_session(session_id).state == "created"
    assert store.get_session(session_id).started_utc is None


# --- trials --------------------------------------------------------------------------------------


def test_trial_round_trip_and_finish(store: Store, clock: Clock) -> None:
    session_id = _session(store, _subject(store).id).id
    created = store.create_trial(session_id, "level walk", "recordings/s1_t1.mcap")
    assert created == schema.Trial(
        id=1,
        session_id=session_id,
        name="level walk",
        status="recording",
        path="recordings/s1_t1.mcap",
        started_utc="2024-05-01T12:00:00+00:00",
    )
    assert store.get_trial(1) == created
    clock.advance(42)
    finished = store.finish_trial(1, "finished", 8400, 41.995)
    assert finished == created.model_copy(
        update={
            "status": "finished",
            "samples": 8400,
            "duration_s": 41.995,
            "stopped_utc": "2024-05-01T12:00:42+00:00",
        }
    )
    assert store.get_trial(1) == finished


def test_trials_by_session_and_status(store: Store) -> None:
    subject_id = _subject(store).id
    s1, s2 = _session(store, subject_id).id, _session(store, subject_id).id
    store.create_trial(s1, "a", "recordings/a.mcap")
    store.create_trial(s2, "b", "uploads/b.mcap", status="uploaded")
    store.create_trial(s1, "c", "recordings/c.mcap")
    store.finish_trial(1, "recovered", 10, 0.05)
    assert [t.name for t in store.list_trials()] == ["a", "b", "c"]
    assert [t.name for t in store.list_trials(session_id=s1)] == ["a", "c"]
    assert [t.name for t in store.list_trials(session_id=s2)] == ["b"]
    assert store.list_trials(session_id=99) == []
    assert [t.name for t in store.trials_with_status("recording")] == ["c"]
    assert [t.name for t in store.trials_with_status("recovered")] == ["a"]
    assert [t.name for t in store.trials_with_status("uploaded")] == ["b"]
    assert store.trials_with_status("finished") == []


# --- events --------------------------------------------------------------------------------------


def test_event_round_trip_keeps_numbers_and_strings(store: Store, clock: Clock) -> None:
    session_id = _session(store, _subject(store).id).id
    clock.advance(1.2345)  # wall_utc keeps milliseconds
    event = store.add_event(
        session_id,
        t=12.5,
        kind="setting",
        text="torque_gain 1.0 -> 0.30000000000000004",
        field="torque_gain",
        before=1.0,
        after=0.1 + 0.2,
        actor="dr.who",
    )
    assert event == schema.Event(
        id=1,
        session_id=session_id,
        t=12.5,
        wall_utc="2024-05-01T12:00:01.234+00:00",
        kind="setting",
        text="torque_gain 1.0 -> 0.30000000000000004",
        field="torque_gain",
        before=1.0,
        after=0.30000000000000004,
        actor="dr.who",
    )
    model = store.add_event(
        session_id, t=13.0, kind="setting", text="model", field="model", before="default", after="1.5"
    )
    integer = store.add_event(session_id, t=14.0, kind="setting", text="n", before=3, after=-0.0)
    note = store.add_event(session_id, t=15.0, kind="annotation", text="stumbled")
    events = store.list_events(session_id)
    assert events == [event, model, integer, note]
    by_id = {e.id: e for e in events}
    assert (by_id[2].before, by_id[2].after) == ("default", "1.5")
    assert type(by_id[3].before) is float and by_id[3].before == 3.0
    assert str(by_id[3].after) == "-0.0"
    assert (by_id[4].field, by_id[4].before, by_id[4].after, by_id[4].actor) == (None, None, None, "system")
    assert type(by_id[1].before) is float and type(by_id[2].before) is str


def test_events_are_listed_by_session_time_then_insertion(store: Store) -> None:
    subject_id = _subject(store).id
    s1, s2 = _session(store, subject_id).id, _session(store, subject_id).id
    for t, text_ in [(5.0, "a"), (1.0, "b"), (5.0, "c"), (0.5, "d")]:
        store.add_event(s1, t=t, kind="system", text=text_)
    store.add_event(s2, t=0.0, kind="system", text="other session")
    assert [e.text for e in store.list_events(s1)] == ["d", "b", "a", "c"]
    assert [e.text for e in store.list_events(s2)] == ["other session"]


def test_trial_events_are_those_logged_with_the_trial(store: Store) -> None:
    subject_id = _subject(store).id
    s1, s2 = _session(store, subject_id).id, _session(store, subject_id).id
    t1 = store.create_trial(s1, "one", "recordings/1.mcap").id
    t2 = store.create_trial(s1, "two", "recordings/2.mcap").id
    store.add_event(s1, t=0.0, kind="system", text="before any trial")
    store.add_event(s1, t=2.0, kind="recording", text="late in one", trial_id=t1)
    store.add_event(s1, t=1.0, kind="recording", text="early in one", trial_id=t1)
    store.add_event(s1, t=3.0, kind="annotation", text="in two", trial_id=t2)
    assert [e.text for e in store.trial_events(t1)] == ["early in one", "late in one"]
    assert [e.text for e in store.trial_events(t2)] == ["in two"]
    assert len(store.list_events(s1)) == 4
    with pytest.raises(Conflict, match=r"^trial 1 belongs to session 1, not 2$"):
        store.add_event(s2, t=0.0, kind="system", text="x", trial_id=t1)
    assert store.list_events(s2) == []


# --- the file ------------------------------------------------------------------------------------


def test_reopening_the_database_sees_the_data(database_url: str, clock: Clock) -> None:
    first = Store(database_url)
    subject = _subject(first)
    session = first.set_session_state(_session(first, subject.id).id, "running")
    trial = first.finish_trial(first.create_trial(session.id, "w", "recordings/w.mcap").id, "finished", 3, 0.01)
    event = first.add_event(session.id, t=0.25, kind="setting", text="g", before=1.0, after="x")
    first.close()

    second = Store(database_url)
    try:
        assert second.list_subjects() == [subject]
        assert second.list_sessions() == [session]
        assert second.list_trials() == [trial]
        assert second.list_events(session.id) == [event]
        assert _subject(second, "AB02").id == 2
    finally:
        second.close()


def test_creates_the_folder_and_uses_wal(tmp_path: Path, clock: Clock) -> None:
    # SQLite-specific (its file, WAL and foreign-key pragma): SQLite in every run.
    path = tmp_path / "data" / "db" / "gaitscope.sqlite"
    s = Store(_url(path))
    try:
        _subject(s)
        assert path.is_file()
        with contextlib.closing(sqlite3.connect(path)) as raw:
            assert raw.execute("PRAGMA journal_mode").fetchone() == ("wal",)
        with s._engine.connect() as conn:
            assert conn.exec_driver_sql("PRAGMA foreign_keys").scalar() == 1
    finally:
        s.close()


def test_in_memory_database_is_shared_by_threads(clock: Clock) -> None:
    # SQLite-specific (in-memory, one connection): SQLite in every run.
    s = Store("sqlite://")
    try:
        session_id = _session(s, _subject(s).id).id
        threads = [
            threading.Thread(target=s.add_event, args=(session_id,), kwargs={"t": i, "kind": "system", "text": "x"})
            for i in range(4)
        ]
        for th in threads:
            th.start()
        for th in threads:
            th.join()
        assert [e.t for e in s.list_events(session_id)] == [0.0, 1.0, 2.0, 3.0]
    finally:
        s.close()


# --- concurrency ---------------------------------------------------------------------------------


def _run_threads(n: int, work: Callable[[int], None]) -> list[BaseException]:
    start = threading.Barrier(n)
    errors: list[BaseException] = []

    def run(k: int) -> None:
        start.wait()
        try:
            work(k)
        except BaseException as exc:
            errors.append(exc)

    threads = [threading.Thread(target=run, args=(k,)) for k in range(n)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    return errors


def test_concurrent_event_writes_are_all_stored(store: Store) -> None:
    subject_id = _subject(store).id
    session_id = _session(store, subject_id).id
    trial_id = store.create_trial(session_id, "w", "recordings/w.mcap").id

    def work(k: int) -> None:
        for i in range(25):
            store.add_event(session_id, t=k + i / 100, kind="system", text=f"{k}:{i}", before=float(i), after=str(k))
            if i % 5 == 0:
                store.set_session_settings(session_id, schema.SessionSettings(torque_gain=k / 10))
        store.add_event(session_id, t=99.0, kind="recording", text=f"done {k}", trial_id=trial_id)

    assert _run_threads(8, work) == []
    events = store.list_events(session_id)
    assert len(events) == 8 * 26
    assert len({e.id for e in events}) == 8 * 26
    assert sorted(e.text for e in events if e.kind == "system") == sorted(
        f"{k}:{i}" for k in range(8) for i in range(25)
    )
    assert all(e.before == float(e.text.split(":")[1]) and e.after == e.text.split(":")[0] for e in events[:-8])
    assert sorted(e.text for e in store.trial_events(trial_id)) == [f"done {k}" for k in range(8)]


def test_concurrent_duplicate_codes_store_exactly_one(store: Store) -> None:
    def work(k: int) -> None:
        _subject(store, "SAME", notes=str(k))

    errors = _run_threads(8, work)
    assert len(errors) == 7
    assert all(isinstance(e, Conflict) for e in errors)
    assert [s.code for s in store.list_subjects()] == ["SAME"]


def test_a_value_the_database_refuses_is_a_conflict_and_changes_nothing(store: Store) -> None:
    # PostgreSQL refuses a NUL character in text (SQLite keeps it): a clean Conflict naming why, not a crash.
    body = schema.SubjectCreate(code="NUL01", leg_length_m=0.9, mass_kg=70.0, notes="a\x00b")
    if store._engine.dialect.name == "postgresql":
        with pytest.raises(Conflict, match=r"^the database refused a value: .*NUL"):
            store.create_subject(body)
        assert store.list_subjects() == []
    else:
        assert store.create_subject(body).notes == "a\x00b"
        assert [s.notes for s in store.list_subjects()] == ["a\x00b"]


class _LockedCursor:
    """A cursor whose ``PRAGMA journal_mode=WAL`` finds the file locked ``times`` times (what SQLite answers
    at once, busy handler or not, while another process locks a file not yet in WAL mode)."""

    def __init__(self, times: int, message: str = "database is locked") -> None:
        self.times, self.message, self.calls = times, message, 0

    def execute(self, sql: str) -> None:
        self.calls += 1
        if self.calls <= self.times:
            raise sqlite3.OperationalError(self.message)


def test_wal_mode_is_asked_again_while_another_process_locks_the_new_file() -> None:
    now = [0.0]
    cursor = _LockedCursor(times=3)
    store_module._set_wal(cursor, clock=lambda: now[0], pause=0.0)
    assert cursor.calls == 4


def test_wal_mode_gives_up_with_sqlites_error_after_the_busy_timeout() -> None:
    now = [0.0]

    def clock() -> float:
        now[0] += 1.0
        return now[0]

    cursor = _LockedCursor(times=10**6)
    with pytest.raises(sqlite3.OperationalError, match="locked"):
        store_module._set_wal(cursor, clock=clock, pause=0.0)
    assert cursor.calls == pytest.approx(store_module.BUSY_TIMEOUT_S, abs=2)


def test_another_error_than_a_lock_is_not_retried() -> None:
    cursor = _LockedCursor(times=1, message="disk I/O error")
    with pytest.raises(sqlite3.OperationalError, match="disk I/O"):
        store_module._set_wal(cursor, clock=lambda: 0.0, pause=0.0)
    assert cursor.calls == 1

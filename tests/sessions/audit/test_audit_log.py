"""The audit trail: the hash chain as documented, tampering found (with the triggers dropped), the triggers
themselves, filters, and appends from many threads and two stores at once.

On the database of the ``database_url`` fixture: PostgreSQL when ``GAITSCOPE_TEST_POSTGRES`` is set, else SQLite.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import itertools
import json
import math
import threading
from collections.abc import Iterator
from typing import Any

import pytest
from sqlalchemy import create_engine, inspect
from sqlalchemy.exc import DBAPIError
from sqlalchemy.pool import NullPool

from sessions import migrations, schema
from sessions.audit import AuditLog, entry_hash
from sessions.audit import log as log_module
from sessions.audit.tables import TRIGGERS, create_triggers, drop_triggers
from sessions.store import Store, make_engine, write_transaction

T0 = dt.datetime(2026, 3, 1, 8, 0, 0, tzinfo=dt.UTC)


@pytest.fixture
def store(database_url: str) -> Iterator[Store]:
    s = Store(database_url)
    yield s
    s.close()


@pytest.fixture
def audit(store: Store) -> AuditLog:
    return AuditLog(store)


def _fill(audit: AuditLog, n: int) -> list[schema.AuditEntry]:
    return [
        audit.record(
            user=f"user{i % 3}",
            role=("admin", "clinician", "experimenter")[i % 3],
            action=("settings.change", "session.start", "login")[i % 3],
            target=f"session {i % 5}",
            before={"torque_gain": 1.0 + i / 10} if i % 3 == 0 else None,
            after={"torque_gain": 1.1 + i / 10, "note": "Ünïcode ✓"} if i % 3 == 0 else None,
            detail="" if i % 4 else f"entry {i}",
        )
        for i in range(n)
    ]


def _raw(database_url: str, *statements: str) -> None:
    """Run SQL behind the audit log's back, as an intruder with an SQL shell would: triggers dropped first."""
    engine = create_engine(database_url, poolclass=NullPool)
    try:
        with engine.begin() as c:
            drop_triggers(c)
            for statement in statements:
                c.exec_driver_sql(statement)
    finally:
        engine.dispose()


# --- the chain --------------------------------------------------------------------------------------


def test_a_chain_of_many_entries_verifies_in_any_chunk_size(audit: AuditLog) -> None:
    entries = _fill(audit, 250)
    assert [e.seq for e in entries] == list(range(1, 251))
    assert entries[0].prev_hash == "0" * 64
    assert all(b.prev_hash == a.hash for a, b in itertools.pairwise(entries))
    for chunk in (1, 7, 250, 5000):
        result = audit.verify(chunk=chunk)
        assert result == schema.AuditVerification(ok=True, entries=250, last_hash=entries[-1].hash)
    assert audit.count() == 250


def test_an_empty_trail_verifies(audit: AuditLog) -> None:
    assert audit.verify() == schema.AuditVerification(ok=True, entries=0)


def test_the_hash_is_the_documented_recipe(audit: AuditLog) -> None:
    """Re-computed here by hand, as an auditor with other tools would: JCS text of the columns but id and hash."""
    e = audit.record(
        user="ana", role="clinician", action="settings.change", target="session 7",
        before={"torque_gain": 1.0}, after={"torque_gain": 1.25, "why": 'a "quote" é'}, detail="line\nbreak",
    )  # fmt: skip
    assert e.before == '{"torque_gain":1.0}'
    assert e.after == '{"torque_gain":1.25,"why":"a \\"quote\\" é"}'
    text_ = (
        '{"action":"settings.change","after":' + json.dumps(e.after, ensure_ascii=False) + ',"before":'
        + json.dumps(e.before) + ',"detail":"line\\nbreak","outcome":"requested","prev_hash":"' + "0" * 64
        + '","role":"clinician","seq":1,"target":"session 7","time_utc":"' + e.time_utc + '","user":"ana"}'
    )  # fmt: skip
    assert e.hash == hashlib.sha256(text_.encode("utf-8")).hexdigest()
    assert len(e.time_utc) == len("2026-03-01T08:00:00.000+00:00") and e.time_utc.endswith("+00:00")


def test_before_and_after_take_models_and_refuse_what_json_cannot_hold(audit: AuditLog) -> None:
    e = audit.record(user="u1", role="admin", action="x", target="t", after=schema.AuditQuery(user="ana"))
    assert json.loads(e.after or "")["user"] == "ana"
    with pytest.raises(ValueError, match="after cannot be stored as JSON"):
        audit.record(user="u1", role="admin", action="x", target="t", after={"gain": math.nan})
    with pytest.raises(ValueError, match="before cannot be stored as JSON: object is not JSON-able"):
        audit.record(user="u1", role="admin", action="x", target="t", before=object())
    with pytest.raises(ValueError, match="outcome 'maybe' is not one of requested, done, failed, refused"):
        audit.record(user="u1", role="admin", action="x", target="t", outcome="maybe")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="user must be 1-64 characters"):
        audit.record(user="", role="admin", action="x", target="t")
    assert audit.count() == 1  # nothing refused was written
    assert audit.verify().ok


# --- tampering (the triggers dropped, as someone with full access to the database could) ---------------


def test_a_changed_entry_is_found(audit: AuditLog, database_url: str) -> None:
    _fill(audit, 30)
    _raw(database_url, "UPDATE audit SET after = '{\"torque_gain\":9.0}' WHERE seq = 17")
    result = audit.verify(chunk=5)
    assert result == schema.AuditVerification(
        ok=False, entries=16, first_bad_seq=17, problem="hash mismatch at seq 17 (the entry was changed)"
    )


def test_a_deleted_entry_is_found(audit: AuditLog, database_url: str) -> None:
    _fill(audit, 30)
    _raw(database_url, "DELETE FROM audit WHERE seq = 18")
    assert audit.verify(chunk=4) == schema.AuditVerification(
        ok=False, entries=17, first_bad_seq=18, problem="seq 18 missing (an entry was deleted)"
    )


def test_a_deleted_first_entry_is_found(audit: AuditLog, database_url: str) -> None:
    _fill(audit, 3)
    _raw(database_url, "DELETE FROM audit WHERE seq = 1")
    result = audit.verify()
    assert (result.ok, result.first_bad_seq, result.problem) == (False, 1, "seq 1 missing (an entry was deleted)")


def test_swapped_entries_are_found(audit: AuditLog, database_url: str) -> None:
    _fill(audit, 10)
    _raw(
        database_url,
        "UPDATE audit SET seq = -1 WHERE seq = 5",
        "UPDATE audit SET seq = 5 WHERE seq = 6",
        "UPDATE audit SET seq = 6 WHERE seq = -1",
    )
    result = audit.verify()
    assert (result.ok, result.entries, result.first_bad_seq) == (False, 4, 5)
    assert result.problem == "hash mismatch at seq 5 (the entry was changed)"


def test_a_changed_and_rehashed_entry_breaks_the_link_to_the_next(audit: AuditLog, database_url: str) -> None:
    """An intruder who knows the recipe re-hashes the entry they changed: the next entry's prev_hash gives it away."""
    entries = _fill(audit, 25)
    old = entries[18]
    forged = {**old.model_dump(exclude={"id", "hash"}), "user": "nobody"}
    _raw(database_url, f"UPDATE audit SET \"user\" = 'nobody', hash = '{entry_hash(forged)}' WHERE seq = 19")
    result = audit.verify(chunk=3)
    assert result == schema.AuditVerification(
        ok=False, entries=19, first_bad_seq=20, problem="prev_hash of seq 20 does not match seq 19"
    )


def test_the_whole_chain_rewritten_from_a_changed_entry_is_not_found_but_the_last_hash_tells(
    audit: AuditLog, database_url: str
) -> None:
    """What a chain cannot find by itself: every later entry re-hashed. The newest hash, noted elsewhere, can."""
    entries = _fill(audit, 6)
    noted = audit.verify().last_hash
    assert noted == entries[-1].hash
    prev = entries[2].hash
    statements = []
    for e in entries[3:]:
        forged = {**e.model_dump(exclude={"id", "hash"}), "prev_hash": prev}
        if e.seq == 4:
            forged["detail"] = "forged"
        h = entry_hash(forged)
        statements.append(
            f"UPDATE audit SET detail = '{forged['detail']}', prev_hash = '{prev}', hash = '{h}' WHERE seq = {e.seq}"
        )
        prev = h
    _raw(database_url, *statements)
    result = audit.verify()
    assert result.ok and result.last_hash != noted


# --- the triggers -------------------------------------------------------------------------------------


def _refused(database_url: str, statement: str) -> str:
    engine = create_engine(database_url, poolclass=NullPool)
    try:
        with pytest.raises(DBAPIError) as caught, engine.begin() as c:
            c.exec_driver_sql(statement)
        return str(caught.value.orig)
    finally:
        engine.dispose()


def test_the_triggers_refuse_update_and_delete(audit: AuditLog, database_url: str) -> None:
    _fill(audit, 3)
    assert "the audit trail is append-only: UPDATE refused" in _refused(
        database_url, "UPDATE audit SET detail = 'x' WHERE seq = 2"
    )
    assert "the audit trail is append-only: DELETE refused" in _refused(database_url, "DELETE FROM audit")
    if database_url.startswith("postgresql"):
        assert "the audit trail is append-only: TRUNCATE refused" in _refused(database_url, "TRUNCATE audit")
    assert audit.count() == 3 and audit.verify().ok


def test_create_triggers_is_idempotent_and_restores_them(audit: AuditLog, database_url: str) -> None:
    _fill(audit, 2)
    _raw(database_url)  # drops them
    engine = create_engine(database_url, poolclass=NullPool)
    try:
        with engine.begin() as c:
            create_triggers(c)
            create_triggers(c)
    finally:
        engine.dispose()
    assert "append-only: DELETE refused" in _refused(database_url, "DELETE FROM audit WHERE seq = 1")


def _triggers(database_url: str) -> set[str]:
    engine = create_engine(database_url, poolclass=NullPool)
    try:
        with engine.connect() as c:
            if c.dialect.name == "sqlite":
                rows = c.exec_driver_sql("SELECT name FROM sqlite_master WHERE type = 'trigger'")
            else:
                rows = c.exec_driver_sql("SELECT tgname FROM pg_trigger WHERE NOT tgisinternal")
            return {r[0] for r in rows}
    finally:
        engine.dispose()


def test_the_migration_makes_the_table_and_triggers_and_its_downgrade_removes_them(database_url: str) -> None:
    Store(database_url).close()  # migrated to head
    expected = set(TRIGGERS) if database_url.startswith("postgresql") else {"audit_no_update", "audit_no_delete"}
    assert _triggers(database_url) >= expected
    engine = make_engine(database_url)
    try:
        with write_transaction(engine) as c:
            migrations.run(c, "0001_baseline", downgrade=True)
        with engine.connect() as c:
            assert "audit" not in inspect(c).get_table_names()
        assert not _triggers(database_url) & expected
        with write_transaction(engine) as c:
            migrations.run(c, "0002_audit")
        with engine.connect() as c:
            assert "audit" in inspect(c).get_table_names()
    finally:
        engine.dispose()
    assert _triggers(database_url) >= expected


# --- reading --------------------------------------------------------------------------------------------


class _Clock:
    def __init__(self) -> None:
        self.now = T0

    def __call__(self) -> dt.datetime:
        self.now += dt.timedelta(minutes=1)
        return self.now


def test_list_filters_pages_newest_first(audit: AuditLog, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(log_module, "_now", _Clock())  # entry i at 08:00 + i+1 minutes
    _fill(audit, 12)
    audit.record(user="eve", role="none", action="refused POST /api/x%_", target="/api/x", outcome="refused")
    assert [e.seq for e in audit.list()] == list(range(13, 0, -1))
    assert [e.seq for e in audit.list(schema.AuditQuery(user="user1"))] == [11, 8, 5, 2]
    assert [e.seq for e in audit.list(schema.AuditQuery(action="session."))] == [11, 8, 5, 2]
    assert [e.seq for e in audit.list(schema.AuditQuery(action="refused POST /api/x%"))] == [13]
    assert audit.list(schema.AuditQuery(action="%")) == []  # a prefix is literal: % is no wildcard
    assert [e.seq for e in audit.list(schema.AuditQuery(outcome="refused"))] == [13]
    assert [e.seq for e in audit.list(schema.AuditQuery(target="session 4"))] == [10, 5]
    window = schema.AuditQuery(since="2026-03-01T08:03:00Z", until="2026-03-01T09:05:00+01:00")
    assert [e.seq for e in audit.list(window)] == [4, 3]  # 08:03 and 08:04: since inclusive, until exclusive
    assert [e.seq for e in audit.list(schema.AuditQuery(limit=5, offset=5))] == [8, 7, 6, 5, 4]
    both = schema.AuditQuery(user="user0", action="settings.", since="2026-03-01T08:05")
    assert [e.seq for e in audit.list(both)] == [10, 7]
    assert [e.seq for e in audit.iter(schema.AuditQuery(user="user2", limit=1), chunk=1)] == [3, 6, 9, 12]


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"since": "yesterday"}, "not an ISO-8601 date or time: 'yesterday'"),
        ({"since": "2026-03-02", "until": "2026-03-01"}, "must be before until"),
        ({"outcome": "maybe"}, "Input should be 'requested', 'done', 'failed' or 'refused'"),
        ({"limit": 0}, "greater than or equal to 1"),
        ({"limit": 1001}, "less than or equal to 1000"),
        ({"colour": "red"}, "Extra inputs are not permitted"),
    ],
)
def test_bad_filters_are_refused_with_a_reason(fields: dict[str, Any], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        schema.AuditQuery(**fields)


def test_a_date_alone_is_midnight_utc() -> None:
    q = schema.AuditQuery(since="2026-03-01", until="2026-03-02T01:00:00+02:00")
    assert (q.since, q.until) == ("2026-03-01T00:00:00.000+00:00", "2026-03-01T23:00:00.000+00:00")


# --- concurrency ----------------------------------------------------------------------------------------


def test_concurrent_appends_keep_the_chain_gap_free(store: Store, database_url: str) -> None:
    """Eight threads on one store and four on a second store (as a second server process would be)."""
    other = Store(database_url)
    logs = [AuditLog(store), AuditLog(other)]
    errors: list[BaseException] = []
    start = threading.Barrier(12)

    def append(worker: int) -> None:
        log = logs[worker % 3 == 2]
        try:
            start.wait()
            for i in range(15):
                log.record(user=f"w{worker}", role="admin", action="test.append", target=str(i), after={"i": i})
        except BaseException as e:  # reported by the assertion below
            errors.append(e)

    threads = [threading.Thread(target=append, args=(w,)) for w in range(12)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    other.close()
    assert errors == []
    entries = list(logs[0].iter())
    assert [e.seq for e in entries] == list(range(1, 181))
    assert sorted(e.time_utc for e in entries) == [e.time_utc for e in entries]  # time never runs backwards
    assert {e.user for e in entries} == {f"w{w}" for w in range(12)}
    assert logs[0].verify(chunk=50) == schema.AuditVerification(ok=True, entries=180, last_hash=entries[-1].hash)

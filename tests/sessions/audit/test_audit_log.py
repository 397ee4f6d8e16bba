"""The audit trail: the hash chain and its MACs as documented, tampering found (with the triggers dropped): edits,
re-hashing, forged appends, truncation against a checkpoint; a trail from before the key; the triggers themselves,
filters, and appends from many threads and two stores at once.

On the database of the ``database_url`` fixture: PostgreSQL when ``GAITSCOPE_TEST_POSTGRES`` is set, else SQLite.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import hmac
import itertools
import json
import math
import stat
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy import create_engine, inspect
from sqlalchemy.exc import DBAPIError
from sqlalchemy.pool import NullPool

from gaitscope.sessions import migrations, schema
from gaitscope.sessions.audit import AuditKeyMismatch, AuditLog, audit_key, checkpoint_mac, entry_hash, entry_mac
from gaitscope.sessions.audit import log as log_module
from gaitscope.sessions.audit.tables import TRIGGERS, create_triggers, drop_triggers
from gaitscope.sessions.errors import DataFormatError
from gaitscope.sessions.store import Store, make_engine, write_transaction

T0 = dt.datetime(2026, 3, 1, 8, 0, 0, tzinfo=dt.UTC)
KEY = b"k" * 32


@pytest.fixture
def store(database_url: str) -> Iterator[Store]:
    s = Store(database_url)
    yield s
    s.close()


@pytest.fixture
def audit(store: Store) -> AuditLog:
    return AuditLog(store, KEY)


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
        assert result == schema.AuditVerification(ok=True, entries=250, last_hash=entries[-1].hash, keyed_from=1)
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
        ok=False, entries=16, first_bad_seq=17, problem="hash mismatch at seq 17 (the entry was changed)", keyed_from=1
    )


def test_a_deleted_entry_is_found(audit: AuditLog, database_url: str) -> None:
    _fill(audit, 30)
    _raw(database_url, "DELETE FROM audit WHERE seq = 18")
    assert audit.verify(chunk=4) == schema.AuditVerification(
        ok=False, entries=17, first_bad_seq=18, problem="seq 18 missing (an entry was deleted)", keyed_from=1
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


def test_a_changed_and_rehashed_entry_is_found_by_its_mac(audit: AuditLog, database_url: str) -> None:
    """An intruder who knows the recipe re-hashes the entry they changed: without the key, its MAC gives it away."""
    entries = _fill(audit, 25)
    old = entries[18]
    forged = {**old.model_dump(exclude={"id", "hash", "mac"}), "user": "nobody"}
    _raw(database_url, f"UPDATE audit SET \"user\" = 'nobody', hash = '{entry_hash(forged)}' WHERE seq = 19")
    result = audit.verify(chunk=3)
    assert result == schema.AuditVerification(
        ok=False, entries=18, first_bad_seq=19, keyed_from=1,
        problem="MAC mismatch at seq 19 (the entry was re-hashed or forged without the key)",
    )  # fmt: skip


def _rechain(entries: list[schema.AuditEntry], changed_seq: int, key: bytes | None) -> list[str]:
    """UPDATEs that change entry ``changed_seq``'s detail and re-hash every entry from it on (re-MAC'd with
    ``key``, or with their MACs kept when None), as an intruder who knows the recipe would."""
    prev = entries[changed_seq - 2].hash if changed_seq > 1 else "0" * 64
    statements = []
    for e in entries[changed_seq - 1 :]:
        forged = {**e.model_dump(exclude={"id", "hash", "mac"}), "prev_hash": prev}
        if e.seq == changed_seq:
            forged["detail"] = "forged"
        h = entry_hash(forged)
        mac = e.mac if key is None else entry_mac(key, h)
        statements.append(
            f"UPDATE audit SET detail = '{forged['detail']}', prev_hash = '{prev}', hash = '{h}', mac = '{mac}' "
            f"WHERE seq = {e.seq}"
        )
        prev = h
    return statements


def test_the_whole_chain_rewritten_from_a_changed_entry_is_found_without_the_key(
    audit: AuditLog, database_url: str
) -> None:
    """Every entry from the changed one re-hashed, so that the SHA-256 chain checks: the MACs do not."""
    entries = _fill(audit, 6)
    _raw(database_url, *_rechain(entries, 4, key=None))
    result = audit.verify()
    assert (result.ok, result.entries, result.first_bad_seq) == (False, 3, 4)
    assert result.problem == "MAC mismatch at seq 4 (the entry was re-hashed or forged without the key)"


def test_the_whole_chain_rewritten_with_the_key_is_found_against_a_checkpoint(
    audit: AuditLog, database_url: str
) -> None:
    """What the MACs cannot find: someone with the key and the database re-makes them. A checkpoint taken before
    (kept elsewhere) still binds them."""
    entries = _fill(audit, 6)
    mark = audit.checkpoint()
    assert (mark.seq, mark.hash) == (6, entries[-1].hash)
    _raw(database_url, *_rechain(entries, 4, key=KEY))
    assert audit.verify().ok  # the chain and its MACs check: only the checkpoint can tell
    result = audit.verify(checkpoint=mark)
    assert (result.ok, result.first_bad_seq) == (False, 6)
    assert result.problem == (
        "seq 6's hash is not the checkpoint's: the trail up to it was rewritten since the checkpoint"
    )


def test_newest_entries_cut_off_are_found_against_a_checkpoint(audit: AuditLog, database_url: str) -> None:
    entries = _fill(audit, 10)
    mark = audit.checkpoint()
    assert audit.verify(checkpoint=mark) == schema.AuditVerification(
        ok=True, entries=10, last_hash=entries[-1].hash, keyed_from=1, checkpoint_seq=10
    )
    audit.record(user="u1", role="admin", action="after.checkpoint", target="t")  # later entries are fine
    assert audit.verify(checkpoint=mark).ok
    _raw(database_url, "DELETE FROM audit WHERE seq >= 9")
    assert audit.verify().ok  # a chain cut at its end is still a chain
    result = audit.verify(checkpoint=mark)
    assert (result.ok, result.entries, result.first_bad_seq) == (False, 8, 9)
    assert result.problem == (
        f"the trail ends at seq 8, but the checkpoint of {mark.time_utc} covers seq 10: entries 9 to 10 were cut off"
    )


def test_a_checkpoint_edited_or_made_with_another_key_is_refused(audit: AuditLog) -> None:
    _fill(audit, 4)
    mark = audit.checkpoint()
    assert audit.verify(checkpoint=mark).ok
    lowered = mark.model_copy(update={"seq": 2, "hash": audit.list()[-2].hash})
    assert not audit.verify(checkpoint=lowered).ok
    other = AuditLog(audit.store, b"x" * 32).checkpoint()
    result = audit.verify(checkpoint=other)
    assert not result.ok and "checkpoint's MAC does not match" in (result.problem or "")


def test_a_checkpoint_is_the_documented_recipe(audit: AuditLog) -> None:
    _fill(audit, 2)
    mark = audit.checkpoint()
    text_ = (
        '{"format":"gaitscope-audit-checkpoint/1","hash":"' + mark.hash + '","seq":2,"time_utc":"' + mark.time_utc
        + '"}'
    )  # fmt: skip
    assert mark.mac == hmac.new(KEY, text_.encode(), hashlib.sha256).hexdigest()
    assert mark.mac == checkpoint_mac(KEY, mark)


def test_a_forged_entry_appended_without_the_key_is_found(audit: AuditLog, database_url: str) -> None:
    entries = _fill(audit, 5)
    last = entries[-1]
    forged = {**last.model_dump(exclude={"id", "hash", "mac"}), "seq": 6, "prev_hash": last.hash, "detail": "forged"}
    columns = ", ".join(f'"{k}"' for k in forged)
    values = ", ".join(
        "NULL" if v is None else (str(v) if isinstance(v, int) else "'" + v + "'") for v in forged.values()
    )
    for mac, problem in (
        ("NULL", "seq 6 has no MAC, though entries are keyed from seq 1 (forged)"),
        ("'" + entry_mac(b"guess" * 8, entry_hash(forged)) + "'",
         "MAC mismatch at seq 6 (the entry was re-hashed or forged without the key)"),
    ):  # fmt: skip
        _raw(
            database_url,
            "DELETE FROM audit WHERE seq = 6",
            f"INSERT INTO audit (id, {columns}, hash, mac) VALUES (1000, {values}, '{entry_hash(forged)}', {mac})",
        )
        result = audit.verify()
        assert (result.ok, result.entries, result.first_bad_seq, result.problem) == (False, 5, 6, problem)


def test_the_mac_is_the_documented_recipe(audit: AuditLog) -> None:
    e = audit.record(user="ana", role="clinician", action="x", target="t")
    assert e.mac == hmac.new(KEY, e.hash.encode("ascii"), hashlib.sha256).hexdigest()


# --- a trail from before the key (migration 0005) ------------------------------------------------------------


def _unkeyed(database_url: str, audit: AuditLog, n: int) -> list[schema.AuditEntry]:
    """``n`` entries as revision 0004 wrote them: no MAC."""
    entries = _fill(audit, n)
    _raw(database_url, "UPDATE audit SET mac = NULL")
    return entries


def test_a_trail_from_before_the_key_is_marked_keyed_and_verifies_its_old_part_by_the_old_rule(
    audit: AuditLog, database_url: str
) -> None:
    _unkeyed(database_url, audit, 7)
    result = audit.verify()
    assert (result.ok, result.first_bad_seq, result.entries) == (False, 7, 7)  # no keyed head: not proven
    assert "the newest entry (seq 7) has no MAC" in (result.problem or "")
    audit.ensure_keyed()
    marker = audit.list()[0]
    assert (marker.seq, marker.action, marker.user, marker.outcome) == (8, "audit.keyed", "server", "done")
    assert "seq 1 to 7 were written before" in marker.detail and marker.mac is not None
    audit.ensure_keyed()  # once only
    _fill(audit, 3)
    result = audit.verify()
    assert (result.ok, result.entries, result.keyed_from) == (True, 11, 8)
    # the old part still checks by the old rule: an edit there is found
    _raw(database_url, "UPDATE audit SET detail = 'x' WHERE seq = 3")
    assert audit.verify().first_bad_seq == 3


def test_macs_stripped_to_pass_for_a_trail_from_before_the_key_are_found(audit: AuditLog, database_url: str) -> None:
    _fill(audit, 5)
    _raw(database_url, "UPDATE audit SET mac = NULL WHERE seq = 5")
    result = audit.verify()
    assert (result.ok, result.first_bad_seq) == (False, 5)
    assert result.problem == "seq 5 has no MAC, though entries are keyed from seq 1 (forged)"
    _raw(database_url, "UPDATE audit SET mac = NULL")
    result = audit.verify()
    assert (result.ok, result.first_bad_seq) == (False, 5)
    assert "the newest entry (seq 5) has no MAC" in (result.problem or "")


def test_another_key_is_refused_before_it_writes(audit: AuditLog) -> None:
    _fill(audit, 2)
    other = AuditLog(audit.store, b"y" * 32)
    with pytest.raises(AuditKeyMismatch, match=r"seq 2\) was not written with this audit key"):
        other.ensure_keyed()
    assert audit.count() == 2
    audit.ensure_keyed()  # the right key: nothing to do
    assert audit.count() == 2


def test_the_key_file_is_made_once_with_0600_and_the_environment_wins(tmp_path: Path) -> None:
    assert audit_key(tmp_path, None, create=False) is None
    key = audit_key(tmp_path, None, create=True)
    path = tmp_path / "audit.key"
    assert key is not None and len(key) == 64 and key == path.read_text().strip().encode()
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert audit_key(tmp_path, None, create=True) == key  # not made again
    assert audit_key(tmp_path, "e" * 40, create=True) == b"e" * 40
    with pytest.raises(DataFormatError, match="GAITSCOPE_AUDIT_KEY: the audit key must be at least 32 characters"):
        audit_key(tmp_path, "short", create=True)
    path.write_text("abc\n")
    with pytest.raises(DataFormatError, match="at least 32 characters, got 3"):
        audit_key(tmp_path, None, create=False)


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
    logs = [AuditLog(store, KEY), AuditLog(other, KEY)]
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
    assert logs[0].verify(chunk=50) == schema.AuditVerification(
        ok=True, entries=180, last_hash=entries[-1].hash, keyed_from=1
    )


def test_processes_starting_together_make_one_key_and_read_it_whole(tmp_path: Path) -> None:
    keys: list[bytes | None] = []
    start = threading.Barrier(8)

    def make() -> None:
        start.wait()
        keys.append(audit_key(tmp_path, None, create=True))

    threads = [threading.Thread(target=make) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(set(keys)) == 1 and keys[0] is not None and len(keys[0]) == 64
    assert sorted(p.name for p in tmp_path.iterdir()) == ["audit.key"]  # no draft left behind

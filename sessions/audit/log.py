"""The audit trail: an append-only, hash-chained record of who changed what (issue #13).

One :class:`AuditLog` per server, over the :class:`~gaitscope.sessions.store.Store`'s database (its table is
:mod:`gaitscope.sessions.audit.tables`). The routes call :meth:`AuditLog.record` *before* a change takes effect, with
outcome ``requested``; the change then happens (or not) in its own transaction.

**The chain.** Entries are numbered ``seq`` = 1, 2, 3... without gaps. Each carries ``prev_hash``, the ``hash``
of the entry before it (64 zeros for the first), and its own ``hash``::

    hash = SHA-256( UTF-8( json.dumps(fields, sort_keys=True, separators=(",", ":"), ensure_ascii=False) ) )

as lower-case hex, where ``fields`` is the JSON object of the entry's columns except ``id`` (the database's row
key, not part of the record) and ``hash`` itself::

    {"action": str, "after": str|null, "before": str|null, "detail": str, "outcome": str,
     "prev_hash": str, "role": str, "seq": int, "target": str, "time_utc": str, "user": str}

``before`` and ``after`` enter as the JSON *text* stored in their columns (a string, or null), not as the values
they encode, so that re-checking needs no float formatting rules. With only strings, null and one integer, this
serialization is RFC 8785's (JCS: keys sorted, no spaces, UTF-8, only ``"``, ``\\`` and control characters
escaped), so an auditor can re-check a row with any JCS implementation, e.g. ``jq -cjS '{action,after,before,
detail,outcome,prev_hash,role,seq,target,time_utc,user}' | sha256sum`` on a row as JSON (jq agrees with JCS on
every character but DEL, which it escapes).

**The key.** A hash chain alone proves nothing against someone who can write the database: they change an entry
and re-hash it and every entry after it, or append an entry of their own, and the chain checks. So each entry
also carries ``mac``, the HMAC-SHA256 (RFC 2104) of its ``hash`` (the 64 hex characters as ASCII) under the
audit key, which is kept outside the database (:mod:`gaitscope.sessions.audit.key`)::

    mac = HMAC-SHA256( key, ASCII(hash) )

Since ``hash`` covers ``prev_hash``, each MAC vouches for its entry and for the whole chain before it.

**Checkpoints** (:meth:`AuditLog.checkpoint`, ``gaitscope audit checkpoint``): the newest ``seq`` and ``hash`` at a
moment, with the HMAC-SHA256 under the key of their canonical JSON (:class:`gaitscope.sessions.schema.AuditCheckpoint`),
written to a small file the admin keeps elsewhere. Checked against one, verification also finds entries cut off
the end, up to the checkpoint.

**What verification finds**: a changed entry (its hash no longer matches), a deleted one (a gap in ``seq``), a
re-ordered or re-hashed one (``prev_hash`` no longer matches the entry before, or, re-chained, its MAC no longer
matches), a forged one (no MAC, or a MAC not made with the key), and, against a checkpoint, entries cut off or
rewritten up to the checkpoint's ``seq``. What it cannot find: entries after the newest checkpoint cut off (the
trail then simply ends earlier; take checkpoints often), or anything done by someone holding both the key and
the database (they can re-make every MAC; only a checkpoint kept where they cannot reach it still binds them).

**Trails from before the key** (migration ``0005_audit_mac``): their entries have no MAC. The first time a server
runs with a key, :meth:`AuditLog.ensure_keyed` appends an ``audit.keyed`` entry, the first with a MAC; entries
before it are checked by the SHA-256 chain only, which :attr:`~gaitscope.sessions.schema.AuditVerification.keyed_from`
reports. After it, an entry without a MAC is a break; so is a trail whose newest entry has none (its MACs
stripped and the chain re-hashed, which makes the whole trail look older than the key).

**Appends serialize**: every append is one write transaction (``BEGIN IMMEDIATE`` on SQLite); on PostgreSQL,
where several server processes may share the database, it first takes the transaction-scoped advisory lock
:data:`LOCK_KEY`, so that two appends never read the same last entry. (The store's write transactions take a
database-wide lock of their own on PostgreSQL today; the chain does not rely on that staying so.)
"""

from __future__ import annotations

import builtins
import datetime as dt
import hashlib
import hmac
import json
from collections.abc import Iterator
from typing import Any, Final

from pydantic import BaseModel
from sqlalchemy import Row, Select, func, select

from gaitscope.sessions import schema
from gaitscope.sessions.audit.tables import AuditRow
from gaitscope.sessions.store import Store

__all__ = ["LOCK_KEY", "VERIFY_CHUNK", "AuditKeyMismatch", "AuditLog", "checkpoint_mac", "entry_hash", "entry_mac"]

#: Key of the PostgreSQL advisory lock that serializes appends: "gs-audit" as a signed 64-bit integer.
LOCK_KEY: Final = int.from_bytes(b"gs-audit", "big", signed=True)
#: Rows read per query while verifying or exporting (so that a million entries never sit in memory at once).
VERIFY_CHUNK: Final = 5000
#: Longest ``detail`` kept; longer ones are cut (an error body can be anything).
DETAIL_MAX: Final = 2000

_AnySelect = Select[*tuple[Any, ...]]
_AnyRow = Row[*tuple[Any, ...]]
_HASHED: Final = ("action", "after", "before", "detail", "outcome", "prev_hash", "role", "seq", "target",
                  "time_utc", "user")  # fmt: skip


def _now() -> dt.datetime:
    """The time of an entry (UTC); a function, so that a test can set the clock."""
    return dt.datetime.now(dt.UTC)


def entry_hash(fields: dict[str, Any]) -> str:
    """The SHA-256 (hex) of an entry's canonical JSON: ``fields`` must hold exactly the hashed columns."""
    text = json.dumps(fields, sort_keys=True, separators=(",", ":"), ensure_ascii=False)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def entry_mac(key: bytes, hash_hex: str) -> str:
    """The HMAC-SHA256 (hex) of an entry's ``hash`` under the audit key."""
    return hmac.new(key, hash_hex.encode("ascii"), hashlib.sha256).hexdigest()


def checkpoint_mac(key: bytes, checkpoint: schema.AuditCheckpoint) -> str:
    """The HMAC-SHA256 (hex) under the audit key of a checkpoint's canonical JSON, its ``mac`` left out."""
    fields = checkpoint.model_dump(mode="json", exclude={"mac"})
    text = json.dumps(fields, sort_keys=True, separators=(",", ":"), ensure_ascii=False)
    return hmac.new(key, text.encode("utf-8"), hashlib.sha256).hexdigest()


class AuditKeyMismatch(ValueError):
    """The audit key is not the one the trail's newest entry was written with."""


def _json_default(value: Any) -> Any:
    if isinstance(value, BaseModel):
        return value.model_dump(mode="json")
    if isinstance(value, (set, frozenset, tuple)):
        return list(value)
    if isinstance(value, (dt.datetime, dt.date)):
        return value.isoformat()
    raise TypeError(f"{type(value).__name__} is not JSON-able")


def _json(value: Any, what: str) -> str | None:
    """``value`` as compact JSON text (None: None); pydantic models as their JSON dump."""
    if value is None:
        return None
    try:
        return json.dumps(
            value, sort_keys=True, separators=(",", ":"), ensure_ascii=False, allow_nan=False, default=_json_default
        )
    except (TypeError, ValueError) as e:
        raise ValueError(f"audit entry's {what} cannot be stored as JSON: {e}") from None


def _entry(row: AuditRow) -> schema.AuditEntry:
    return schema.AuditEntry.model_validate(row, from_attributes=True)


def _filtered(query: schema.AuditQuery) -> Select[AuditRow]:
    """The rows matching ``query``'s filters (not its paging). Prefixes match literally (``%`` and ``_`` too)."""
    stmt = select(AuditRow)
    if query.user is not None:
        stmt = stmt.where(AuditRow.user == query.user)
    if query.action is not None:
        stmt = stmt.where(AuditRow.action.startswith(query.action, autoescape=True))
    if query.target is not None:
        stmt = stmt.where(AuditRow.target.startswith(query.target, autoescape=True))
    if query.outcome is not None:
        stmt = stmt.where(AuditRow.outcome == query.outcome)
    if query.since is not None:
        stmt = stmt.where(AuditRow.time_utc >= query.since)
    if query.until is not None:
        stmt = stmt.where(AuditRow.time_utc < query.until)
    return stmt


class AuditLog:
    """The audit trail in ``store``'s database: :meth:`record`, :meth:`list`, :meth:`iter`, :meth:`verify`,
    :meth:`checkpoint`. ``key``: the audit key (:func:`gaitscope.sessions.audit.key.audit_key`); every entry appended
    carries its MAC."""

    def __init__(self, store: Store, key: bytes) -> None:
        if not key:
            raise ValueError("the audit trail needs its key (gaitscope.sessions.audit.key.audit_key)")
        self.store = store
        self._key = key

    def ensure_keyed(self, user: str = "server") -> None:
        """Check that the trail's newest entry was written with this key, or, if it has no MAC (a trail from
        before the key), append the ``audit.keyed`` entry that starts the keyed part. Nothing on an empty trail.

        Raises:
            AuditKeyMismatch: the newest entry's MAC is not this key's: another process writes with another key
                (give every process the same ``GAITSCOPE_AUDIT_KEY``), or the entry was forged.
        """
        with self.store.reading() as session:
            last = session.execute(
                select(AuditRow.seq, AuditRow.hash, AuditRow.mac).order_by(AuditRow.seq.desc()).limit(1)
            ).first()
        if last is None:
            return
        if last.mac is None:
            self.record(
                user=user, role="admin", action="audit.keyed", target="audit", outcome="done",
                detail=f"entries from here on carry an HMAC-SHA256 under the audit key; seq 1 to {last.seq} were "
                "written before and are checked by the SHA-256 chain only",
            )  # fmt: skip
            return
        if not hmac.compare_digest(entry_mac(self._key, last.hash), last.mac):
            raise AuditKeyMismatch(
                f"the audit trail's newest entry (seq {last.seq}) was not written with this audit key: every "
                "process writing to the trail needs the same key (GAITSCOPE_AUDIT_KEY, or the data folder's "
                "audit.key); run 'gaitscope audit verify' to see whether the trail was tampered with"
            )

    def checkpoint(self) -> schema.AuditCheckpoint:
        """The trail's head now (newest ``seq`` and ``hash``; 0 and 64 zeros when empty), signed with the key."""
        with self.store.reading() as session:
            last = session.execute(select(AuditRow.seq, AuditRow.hash).order_by(AuditRow.seq.desc()).limit(1)).first()
        unsigned = schema.AuditCheckpoint(
            seq=0 if last is None else last.seq,
            hash=schema.AUDIT_GENESIS if last is None else last.hash,
            time_utc=_now().isoformat(timespec="milliseconds"),
            mac="0" * 64,
        )
        return unsigned.model_copy(update={"mac": checkpoint_mac(self._key, unsigned)})

    def record(
        self,
        *,
        user: str,
        role: str,
        action: str,
        target: str,
        before: Any = None,
        after: Any = None,
        outcome: schema.AuditOutcome = "requested",
        detail: str = "",
    ) -> schema.AuditEntry:
        """Append one entry and return it; committed when this returns.

        ``before`` and ``after``: anything JSON can hold (pydantic models as their JSON dump), or None. Cost: one
        indexed read of the newest entry and one insert, in one transaction.

        Raises:
            ValueError: ``before``/``after`` are not JSON-able (NaN included), ``outcome`` is not one of
                :data:`gaitscope.sessions.schema.AUDIT_OUTCOMES`, or ``user``/``role``/``action`` are empty or too long.
        """
        if outcome not in schema.AUDIT_OUTCOMES:
            raise ValueError(f"audit outcome {outcome!r} is not one of {', '.join(schema.AUDIT_OUTCOMES)}")
        for what, value, longest in (("user", user, 64), ("role", role, 16), ("action", action, 128)):
            if not value or len(value) > longest:
                raise ValueError(f"audit entry's {what} must be 1-{longest} characters, got {value!r}")
        fields: dict[str, Any] = {
            "user": user,
            "role": role,
            "action": action,
            "target": target,
            "before": _json(before, "before"),
            "after": _json(after, "after"),
            "outcome": outcome,
            "detail": detail[:DETAIL_MAX],
        }
        with self.store.writing() as session:
            if session.get_bind().dialect.name == "postgresql":
                session.connection().exec_driver_sql(f"SELECT pg_advisory_xact_lock({LOCK_KEY})")
            last = session.execute(select(AuditRow.seq, AuditRow.hash).order_by(AuditRow.seq.desc()).limit(1)).first()
            # The time is taken under the lock, so that times never decrease along the chain.
            fields["time_utc"] = _now().isoformat(timespec="milliseconds")
            fields["seq"] = 1 if last is None else last.seq + 1
            fields["prev_hash"] = schema.AUDIT_GENESIS if last is None else last.hash
            digest = entry_hash(fields)
            row = AuditRow(**fields, hash=digest, mac=entry_mac(self._key, digest))
            session.add(row)
            session.flush()  # assigns the id
            return _entry(row)

    def list(self, query: schema.AuditQuery | None = None) -> builtins.list[schema.AuditEntry]:
        """The entries matching ``query``, newest first, one page (``limit`` from ``offset``)."""
        query = query or schema.AuditQuery()
        stmt = _filtered(query).order_by(AuditRow.seq.desc()).limit(query.limit).offset(query.offset)
        with self.store.reading() as session:
            return [_entry(row) for row in session.scalars(stmt)]

    def iter(self, query: schema.AuditQuery | None = None, chunk: int = VERIFY_CHUNK) -> Iterator[schema.AuditEntry]:
        """Every entry matching ``query``'s filters (its paging ignored), oldest first, read ``chunk`` at a time
        (each chunk its own short read, so that an export of the whole trail holds no long transaction)."""
        stmt = _filtered(query or schema.AuditQuery())
        for rows in self._chunks(stmt.add_columns(AuditRow.seq), chunk):
            yield from (_entry(row[0]) for row in rows)

    def _chunks(self, stmt: _AnySelect, chunk: int) -> Iterator[builtins.list[_AnyRow]]:
        """``stmt``'s rows by ascending ``seq``, ``chunk`` per query (keyset paging on the unique ``seq``).
        ``stmt`` selects ``AuditRow.seq`` as its last column (the paging's key)."""
        after = 0
        while True:
            with self.store.reading() as session:
                page = stmt.where(AuditRow.seq > after).order_by(AuditRow.seq).limit(chunk)
                rows = builtins.list(session.execute(page).all())
            if not rows:
                return
            yield rows
            after = rows[-1][-1]

    def count(self) -> int:
        """How many entries there are (the newest ``seq``, when the chain is intact)."""
        with self.store.reading() as session:
            return session.scalar(select(func.count()).select_from(AuditRow)) or 0

    def verify(
        self, chunk: int = VERIFY_CHUNK, checkpoint: schema.AuditCheckpoint | None = None
    ) -> schema.AuditVerification:
        """Walk the chain from seq 1 and report the first break, if any (streaming, ``chunk`` rows at a time).

        In order, for each entry: its ``seq`` must be the one expected (a gap: an entry was deleted; a repeat: one
        was copied), its hash must match its fields (else it was changed), its ``prev_hash`` must be the hash of
        the entry before (else entries were re-ordered, or one was changed and re-hashed), and its MAC must be the
        key's for its hash (else it was re-hashed or forged without the key); once one entry has a MAC, every later
        one must, and so must the newest. With ``checkpoint`` (signed with this key), the trail must reach its
        ``seq`` and have its ``hash`` there (else entries were cut off, or rewritten by someone with the key).
        """
        if checkpoint is not None and not hmac.compare_digest(checkpoint_mac(self._key, checkpoint), checkpoint.mac):
            return schema.AuditVerification(
                ok=False, entries=0, problem="the checkpoint's MAC does not match: it was edited, or made with "
                "another audit key",
            )  # fmt: skip
        checked = 0
        prev_hash = schema.AUDIT_GENESIS
        keyed_from: int | None = None
        at_checkpoint: str | None = schema.AUDIT_GENESIS if checkpoint is not None and checkpoint.seq == 0 else None
        # Plain tuples of the columns (seq last, the paging's key), not ORM objects nor attribute access: a million
        # entries take a third of the time.
        names = [name for name in _HASHED if name != "seq"]
        columns = select(AuditRow.hash, AuditRow.mac, *(getattr(AuditRow, name) for name in names), AuditRow.seq)
        for rows in self._chunks(columns, chunk):
            for row in rows:
                stored, mac, *values, seq = row
                fields = dict(zip(names, values, strict=True))
                fields["seq"] = seq
                expected = checked + 1
                problem = None
                if seq > expected:
                    problem, bad = f"seq {expected} missing (an entry was deleted)", expected
                elif seq < expected:  # only if the unique constraint was dropped too
                    problem, bad = f"seq {seq} appears twice (an entry was copied)", seq
                elif entry_hash(fields) != stored:
                    problem, bad = f"hash mismatch at seq {seq} (the entry was changed)", seq
                elif fields["prev_hash"] != prev_hash:
                    problem = (
                        f"prev_hash of seq {seq} does not match seq {seq - 1}"
                        if seq > 1
                        else "prev_hash of seq 1 is not 64 zeros"
                    )
                    bad = seq
                elif mac is None and keyed_from is not None:
                    problem = f"seq {seq} has no MAC, though entries are keyed from seq {keyed_from} (forged)"
                    bad = seq
                elif mac is not None and not hmac.compare_digest(entry_mac(self._key, stored), mac):
                    problem = f"MAC mismatch at seq {seq} (the entry was re-hashed or forged without the key)"
                    bad = seq
                if problem is not None:
                    return schema.AuditVerification(
                        ok=False, entries=checked, first_bad_seq=bad, problem=problem, keyed_from=keyed_from
                    )
                if mac is not None and keyed_from is None:
                    keyed_from = seq
                checked += 1
                prev_hash = stored
                if checkpoint is not None and seq == checkpoint.seq:
                    at_checkpoint = stored
        result = schema.AuditVerification(
            ok=True, entries=checked, last_hash=prev_hash if checked else None, keyed_from=keyed_from
        )
        if checked and keyed_from is None:
            return result.model_copy(update={
                "ok": False, "first_bad_seq": checked,
                "problem": f"the newest entry (seq {checked}) has no MAC: the trail was rewritten without the key, "
                "or no server has run with the key since the upgrade (start one once)",
            })  # fmt: skip
        if checkpoint is not None:
            if checked < checkpoint.seq:
                return result.model_copy(update={
                    "ok": False, "first_bad_seq": checked + 1,
                    "problem": f"the trail ends at seq {checked}, but the checkpoint of {checkpoint.time_utc} "
                    f"covers seq {checkpoint.seq}: entries {checked + 1} to {checkpoint.seq} were cut off",
                })  # fmt: skip
            if at_checkpoint != checkpoint.hash:
                return result.model_copy(update={
                    "ok": False, "first_bad_seq": checkpoint.seq,
                    "problem": f"seq {checkpoint.seq}'s hash is not the checkpoint's: the trail up to it was "
                    "rewritten since the checkpoint",
                })  # fmt: skip
            result = result.model_copy(update={"checkpoint_seq": checkpoint.seq})
        return result

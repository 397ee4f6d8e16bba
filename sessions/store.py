"""The database: subjects, their sessions, the sessions' trials and events (SQLite by default).

:class:`Store` takes any SQLAlchemy URL. Every public method is one short transaction on its own ORM
session, so one :class:`Store` may be shared by the threads of a FastAPI thread pool, and every method
returns the wire classes of :mod:`gaitscope.sessions.schema`, never ORM rows. A write builds (and so validates)
its result before it commits: a value the schema refuses, like a failed insert, rolls the whole write
back and leaves the database as it was.

Times are ISO-8601 UTC strings, to the second (``created_utc``, ``started_utc``, ``stopped_utc``) or,
for events' ``wall_utc``, to the millisecond. Uploads in progress are not stored here (the server keeps
them on disk).

With SQLite the journal is WAL (readers never block the writer), foreign keys are enforced, and
SQLAlchemy rather than the ``sqlite3`` driver emits ``BEGIN``: a read gets a plain ``BEGIN`` (one
consistent snapshot), a write ``BEGIN IMMEDIATE``, so that it takes the write lock before it reads and
waits up to :data:`BUSY_TIMEOUT_S` for another writer instead of failing halfway through
(https://docs.sqlalchemy.org/en/20/dialects/sqlite.html#sqlite-transactions).
"""

from __future__ import annotations

import contextlib
import datetime as dt
import importlib
import importlib.util
import json
import sqlite3
import threading
import time
import weakref
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, ClassVar, Final, TypeVar

from pydantic import TypeAdapter
from sqlalchemy import (
    BigInteger,
    Connection,
    Engine,
    ForeignKey,
    Index,
    Integer,
    MetaData,
    String,
    Text,
    create_engine,
    event,
    func,
    make_url,
    orm,
    select,
)
from sqlalchemy.engine import URL
from sqlalchemy.exc import DataError, IntegrityError
from sqlalchemy.orm import DeclarativeBase, Mapped, mapped_column
from sqlalchemy.pool import StaticPool
from sqlalchemy.sql import ColumnElement

from gaitscope.sessions import schema

#: Seconds a SQLite writer waits for another one to commit before it fails with "database is locked".
BUSY_TIMEOUT_S: Final = 30.0

_WRITE: Final = "gaitscope_write"  # execution option of a write transaction (BEGIN IMMEDIATE on SQLite)
_SOURCE: Final = TypeAdapter(schema.SourceSpec)


class NotFound(LookupError):
    """No row has the id; the message names the kind and the id ("session 7 does not exist")."""


class Conflict(ValueError):
    """A write contradicts stored data ("subject code 'AB01' exists"); nothing was written."""


# --- tables --------------------------------------------------------------------------------------


class _Base(DeclarativeBase):
    # Every ``Mapped[int]`` (ids, counts) is BIGINT on PostgreSQL, which is what the API admits
    # (schema.INT64_MAX); INTEGER on SQLite, which is 64-bit there already and where only
    # ``INTEGER PRIMARY KEY`` is the rowid that numbers new rows by itself.
    type_annotation_map: ClassVar[dict[Any, Any]] = {int: BigInteger().with_variant(Integer(), "sqlite")}


#: The declarative base of every table; ``sessions.accounts`` and ``sessions.audit`` declare theirs on it.
Base = _Base

#: The modules besides this one that declare tables on :data:`Base` (each imported if it exists).
_TABLE_MODULES: Final = (
    "gaitscope.sessions.accounts.tables",
    "gaitscope.sessions.audit.tables",
    "gaitscope.sessions.cluster.tables",
    "gaitscope.sessions.mappings.tables",
    "gaitscope.sessions.personalization.tables",
)


def all_metadata() -> MetaData:
    """Every table of the database: this module's and those of :data:`_TABLE_MODULES`, imported here.

    What the migrations (``sessions/migrations``) are compared with: a table is in the metadata only
    once the module that declares it has been imported, and nothing else need import it first.
    """
    for name in _TABLE_MODULES:
        if importlib.util.find_spec(name.rpartition(".")[0]) and importlib.util.find_spec(name):
            importlib.import_module(name)
    return _Base.metadata


class _SubjectRow(_Base):
    __tablename__ = "subjects"

    id: Mapped[int] = mapped_column(primary_key=True)
    code: Mapped[str] = mapped_column(String(32), unique=True)
    leg_length_m: Mapped[float]
    mass_kg: Mapped[float]
    side: Mapped[str] = mapped_column(String(8))
    notes: Mapped[str] = mapped_column(Text)
    created_utc: Mapped[str] = mapped_column(String(40))


class _SessionRow(_Base):
    __tablename__ = "sessions"

    id: Mapped[int] = mapped_column(primary_key=True)
    subject_id: Mapped[int] = mapped_column(ForeignKey("subjects.id"), index=True)
    source: Mapped[str] = mapped_column(Text)  # SourceSpec as JSON
    settings: Mapped[str] = mapped_column(Text)  # SessionSettings as JSON
    state: Mapped[str] = mapped_column(String(16), index=True)
    created_utc: Mapped[str] = mapped_column(String(40))
    started_utc: Mapped[str | None] = mapped_column(String(40))
    stopped_utc: Mapped[str | None] = mapped_column(String(40))
    node: Mapped[str | None] = mapped_column(String(128))  # the process that runs it (Settings.node)


class _TrialRow(_Base):
    __tablename__ = "trials"

    id: Mapped[int] = mapped_column(primary_key=True)
    session_id: Mapped[int] = mapped_column(ForeignKey("sessions.id"), index=True)
    name: Mapped[str] = mapped_column(Text)
    status: Mapped[str] = mapped_column(String(16), index=True)
    path: Mapped[str] = mapped_column(Text)
    started_utc: Mapped[str] = mapped_column(String(40))
    stopped_utc: Mapped[str | None] = mapped_column(String(40))
    samples: Mapped[int] = mapped_column(default=0)
    duration_s: Mapped[float] = mapped_column(default=0.0)


class _EventRow(_Base):
    __tablename__ = "events"
    __table_args__ = (Index("ix_events_session_t", "session_id", "t"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    session_id: Mapped[int] = mapped_column(ForeignKey("sessions.id"))
    trial_id: Mapped[int | None] = mapped_column(ForeignKey("trials.id"), index=True)
    t: Mapped[float]
    wall_utc: Mapped[str] = mapped_column(String(40))
    kind: Mapped[str] = mapped_column(String(16))
    text: Mapped[str] = mapped_column(Text)
    field: Mapped[str | None] = mapped_column(String(64))
    before: Mapped[str | None] = mapped_column(Text)  # JSON: a number or a string (_encode_value)
    after: Mapped[str | None] = mapped_column(Text)
    actor: Mapped[str] = mapped_column(String(64))


class _PersonalizationRow(_Base):
    __tablename__ = "personalizations"
    __table_args__ = (Index("ix_personalizations_subject_model", "subject_id", "model"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    subject_id: Mapped[int] = mapped_column(ForeignKey("subjects.id"))
    version: Mapped[int]
    model: Mapped[str] = mapped_column(String(32))
    fingerprint: Mapped[str] = mapped_column(Text)  # JSON list of floats
    fit_rmse_avg_deg: Mapped[float]
    fit_rmse_personal_deg: Mapped[float]
    source_trial_id: Mapped[int | None] = mapped_column(ForeignKey("trials.id"))
    strides_used: Mapped[int]
    strides_excluded: Mapped[int]
    seconds_used: Mapped[float]
    excluded: Mapped[str] = mapped_column(Text)  # JSON {reason: count}
    stride_length_source: Mapped[str] = mapped_column(String(64))
    state: Mapped[str] = mapped_column(String(16))
    created_utc: Mapped[str] = mapped_column(String(40))
    created_by: Mapped[str] = mapped_column(String(64))
    promoted_utc: Mapped[str | None] = mapped_column(String(40))
    promoted_by: Mapped[str | None] = mapped_column(String(64))
    retired_utc: Mapped[str | None] = mapped_column(String(40))
    retired_by: Mapped[str | None] = mapped_column(String(64))
    replaced_id: Mapped[int | None]  # the personalization that was active when this one was promoted
    note: Mapped[str] = mapped_column(Text)


class _ImuCalibrationRow(_Base):
    """An accepted IMU mounting calibration; a subject's latest is their current one."""

    __tablename__ = "imu_calibrations"

    id: Mapped[int] = mapped_column(primary_key=True)
    subject_id: Mapped[int] = mapped_column(ForeignKey("subjects.id"), index=True)
    session_id: Mapped[int] = mapped_column(ForeignKey("sessions.id"), index=True)
    trial_id: Mapped[int | None] = mapped_column(ForeignKey("trials.id"))
    duration_s: Mapped[float]
    sensors: Mapped[str] = mapped_column(Text)  # JSON list of ImuSensorCalibration
    created_utc: Mapped[str] = mapped_column(String(40))
    created_by: Mapped[str] = mapped_column(String(64))
    note: Mapped[str] = mapped_column(Text)


_Row = TypeVar("_Row", _SubjectRow, _SessionRow, _TrialRow, _EventRow, _PersonalizationRow, _ImuCalibrationRow)
_KIND: Final[dict[type[_Base], str]] = {
    _SubjectRow: "subject",
    _SessionRow: "session",
    _TrialRow: "trial",
    _EventRow: "event",
    _PersonalizationRow: "personalization",
    _ImuCalibrationRow: "IMU calibration",
}
_IMU_SENSORS: Final = TypeAdapter(list[schema.ImuSensorCalibration])


# --- rows to wire classes ------------------------------------------------------------------------


def _subject(row: _SubjectRow) -> schema.Subject:
    return schema.Subject.model_validate(row, from_attributes=True)


def _session(row: _SessionRow) -> schema.Session:
    return schema.Session.model_validate(
        {
            "id": row.id,
            "subject_id": row.subject_id,
            "source": _SOURCE.validate_json(row.source, context={"stored": True}),  # an old rate reads as the limit
            "settings": schema.SessionSettings.model_validate_json(row.settings),
            "state": row.state,
            "created_utc": row.created_utc,
            "started_utc": row.started_utc,
            "stopped_utc": row.stopped_utc,
            "node": row.node,
        }
    )


def _trial(row: _TrialRow) -> schema.Trial:
    return schema.Trial.model_validate(row, from_attributes=True)


def _event(row: _EventRow) -> schema.Event:
    return schema.Event.model_validate(
        {
            "id": row.id,
            "session_id": row.session_id,
            "t": row.t,
            "wall_utc": row.wall_utc,
            "kind": row.kind,
            "text": row.text,
            "field": row.field,
            "before": _decode_value(row.before),
            "after": _decode_value(row.after),
            "actor": row.actor,
        }
    )


def _personalization(row: _PersonalizationRow) -> schema.Personalization:
    fields = {c: getattr(row, c) for c in schema.Personalization.model_fields if c not in ("fingerprint", "excluded")}
    return schema.Personalization.model_validate(
        {**fields, "fingerprint": json.loads(row.fingerprint), "excluded": json.loads(row.excluded)}
    )


def _imu_calibration(row: _ImuCalibrationRow) -> schema.ImuCalibration:
    fields = {c: getattr(row, c) for c in schema.ImuCalibration.model_fields if c not in ("sensors", "ok", "reason")}
    return schema.ImuCalibration.model_validate(
        {**fields, "ok": True, "sensors": _IMU_SENSORS.validate_json(row.sensors)}
    )


def _encode_value(value: float | str | None) -> str | None:
    """An event's before/after as JSON, numbers always as floats: 1 -> "1.0", "default" -> '"default"'."""
    if value is None:
        return None
    if isinstance(value, str):
        return json.dumps(value)
    return json.dumps(float(value))


def _decode_value(text: str | None) -> float | str | None:
    if text is None:
        return None
    value = json.loads(text)
    return value if isinstance(value, str) else float(value)


def _now() -> dt.datetime:
    return dt.datetime.now(dt.UTC)


def _stamp() -> str:
    return _now().isoformat(timespec="seconds")


# --- SQLite --------------------------------------------------------------------------------------


def _sqlite_engine(url: URL) -> Engine:
    memory = url.database in (None, "", ":memory:")
    if not memory and not url.query.get("uri"):
        Path(str(url.database)).parent.mkdir(parents=True, exist_ok=True)
    kwargs: dict[str, Any] = {"connect_args": {"check_same_thread": False, "timeout": BUSY_TIMEOUT_S}}
    if memory:
        kwargs["poolclass"] = StaticPool  # one connection, or every thread would see its own database
    engine = create_engine(url, **kwargs)
    event.listen(engine, "connect", _on_sqlite_connect)
    event.listen(engine, "begin", _on_sqlite_begin)
    return engine


def _on_sqlite_connect(dbapi_connection: Any, _record: Any) -> None:
    dbapi_connection.isolation_level = None  # the driver emits no BEGIN of its own; _on_sqlite_begin does
    cursor = dbapi_connection.cursor()
    try:
        _set_wal(cursor)
        cursor.execute("PRAGMA foreign_keys=ON")
    finally:
        cursor.close()


def _set_wal(cursor: Any, clock: Callable[[], float] = time.monotonic, pause: float = 0.05) -> None:
    """Put the database in WAL mode (a persistent setting of the file: kept once set). Switching needs the
    file's exclusive lock, and SQLite answers "database is locked" at once, without its busy handler, while
    another process holds a lock on a file that is not in WAL mode yet (two processes opening one new
    database, CI): so it is asked again until :data:`BUSY_TIMEOUT_S` has passed, then the error is raised."""
    deadline = clock() + BUSY_TIMEOUT_S
    while True:
        try:
            cursor.execute("PRAGMA journal_mode=WAL")
            return
        except sqlite3.OperationalError as exc:
            if ("locked" not in str(exc) and "busy" not in str(exc)) or clock() >= deadline:
                raise
        time.sleep(pause)


def _on_sqlite_begin(connection: Connection) -> None:
    write = connection.get_execution_options().get(_WRITE, False)
    connection.exec_driver_sql("BEGIN IMMEDIATE" if write else "BEGIN")


# --- any database --------------------------------------------------------------------------------


def make_engine(url: str | URL) -> Engine:
    """The engine :class:`Store` uses for ``url`` (SQLite set up as the module says; for a file, its
    folder created). Also what ``gaitscope db`` migrates with."""
    parsed = make_url(url)
    if parsed.get_backend_name() == "sqlite":
        return _sqlite_engine(parsed)
    return create_engine(parsed, pool_pre_ping=True)  # a database server's restart drops pooled connections


def _lock_writes(connection: Connection) -> None:
    """PostgreSQL: wait for the write lock (held until this transaction ends). SQLite's is BEGIN IMMEDIATE."""
    if connection.dialect.name == "postgresql":
        from gaitscope.sessions.migrations import LOCK_KEY

        connection.exec_driver_sql(f"SELECT pg_advisory_xact_lock({LOCK_KEY})")


@contextlib.contextmanager
def write_transaction(engine: Engine) -> Iterator[Connection]:
    """One write transaction on a connection of ``engine``, holding the database's write lock (SQLite
    ``BEGIN IMMEDIATE``, PostgreSQL an advisory lock); committed when the block ends without error."""
    with engine.connect() as connection:
        connection.execution_options(**{_WRITE: True})
        with connection.begin():
            _lock_writes(connection)
            yield connection


# --- the store -----------------------------------------------------------------------------------


class Store:
    """Subjects, sessions, trials and events in the database at ``url``: SQLite or PostgreSQL
    (``postgresql+psycopg://user:password@host/database``).

    Brings the database to the newest migration when it opens it (:func:`gaitscope.sessions.migrations.migrate`:
    creates a new one, upgrades an old one in place; for a SQLite file it creates the folder too). An
    in-memory SQLite database (``sqlite://``) is one connection shared by all threads, one call at a time.

    On PostgreSQL a write transaction first takes one advisory lock (``pg_advisory_xact_lock``), so
    that writes are serialised as on SQLite (``BEGIN IMMEDIATE``) and the methods' read-then-write
    steps (a personalization's next version, the one active personalization) hold across processes.
    """

    def __init__(self, url: str) -> None:
        parsed = make_url(url)
        self._lock: contextlib.AbstractContextManager[Any] = contextlib.nullcontext()
        if parsed.get_backend_name() == "sqlite" and parsed.database in (None, "", ":memory:"):
            self._lock = threading.Lock()
        self._engine = make_engine(parsed)
        self._factory = orm.sessionmaker(self._engine, expire_on_commit=False)
        from gaitscope.sessions import migrations  # here: the migrations import this module

        # The write lock first: two processes opening one new database do not both create it.
        with self._lock, write_transaction(self._engine) as connection:
            migrations.migrate(connection)
        # A store dropped without close() still closes its connections (psycopg warns about open ones).
        weakref.finalize(self, self._engine.dispose)

    def close(self) -> None:
        """Close every pooled connection (a SQLite WAL file is checkpointed and removed)."""
        self._engine.dispose()

    # --- transactions -----------------------------------------------------------------------------

    @contextlib.contextmanager
    def _read(self) -> Iterator[orm.Session]:
        with self._lock, self._factory() as session:
            yield session  # closed with a rollback: reads never write

    @contextlib.contextmanager
    def _write(self) -> Iterator[orm.Session]:
        try:
            with self._lock, self._factory.begin() as session:  # commits on success, else rolls back
                _lock_writes(session.connection(execution_options={_WRITE: True}))
                yield session
        except DataError as exc:  # PostgreSQL: a string longer than its column, a NUL character, ...
            detail = str(exc.orig).splitlines()[0] if exc.orig is not None else type(exc).__name__
            raise Conflict(f"the database refused a value: {detail}") from exc

    def reading(self) -> contextlib.AbstractContextManager[orm.Session]:
        """A read transaction, for the modules whose tables share this database (``gaitscope.sessions.accounts``)."""
        return self._read()

    def writing(self) -> contextlib.AbstractContextManager[orm.Session]:
        """A write transaction (``BEGIN IMMEDIATE`` on SQLite), committed when the block ends without error."""
        return self._write()

    @staticmethod
    def _get(session: orm.Session, cls: type[_Row], row_id: int, *, for_update: bool = False) -> _Row:
        if not 0 < row_id <= schema.INT64_MAX:  # no such row; and SQLite cannot even take the number
            raise NotFound(f"{_KIND[cls]} {row_id} does not exist")
        row = session.get(cls, row_id, with_for_update=for_update)
        if row is None:
            raise NotFound(f"{_KIND[cls]} {row_id} does not exist")
        return row

    # --- subjects ---------------------------------------------------------------------------------

    def create_subject(self, body: schema.SubjectCreate) -> schema.Subject:
        """A new subject; :class:`Conflict` if its code exists."""
        try:
            with self._write() as session:
                # Checked first, under the write lock, rather than left to the unique index: a failed insert
                # would use up an id on PostgreSQL (its sequences do not roll back).
                if session.scalar(select(_SubjectRow.id).where(_SubjectRow.code == body.code)) is not None:
                    raise Conflict(f"subject code {body.code!r} exists")
                row = _SubjectRow(**body.model_dump(), created_utc=_stamp())
                session.add(row)
                session.flush()
                return _subject(row)
        except IntegrityError as exc:  # the only constraint an insert can break is the unique code
            raise Conflict(f"subject code {body.code!r} exists") from exc

    def list_subjects(self) -> list[schema.Subject]:
        """Every subject, in the order they were created."""
        with self._read() as session:
            return [_subject(r) for r in session.scalars(select(_SubjectRow).order_by(_SubjectRow.id))]

    def get_subject(self, subject_id: int) -> schema.Subject:
        with self._read() as session:
            return _subject(self._get(session, _SubjectRow, subject_id))

    # --- sessions ---------------------------------------------------------------------------------

    def create_session(self, body: schema.SessionCreate) -> schema.Session:
        """A new session in state ``created`` (``body.start`` is the caller's to act on)."""
        with self._write() as session:
            self._get(session, _SubjectRow, body.subject_id)
            row = _SessionRow(
                subject_id=body.subject_id,
                source=body.source.model_dump_json(),
                settings=body.settings.model_dump_json(),
                state="created",
                created_utc=_stamp(),
            )
            session.add(row)
            session.flush()
            return _session(row)

    def list_sessions(self, subject_id: int | None = None) -> list[schema.Session]:
        """Sessions, newest first; those of one subject when ``subject_id`` is given."""
        query = select(_SessionRow).order_by(_SessionRow.id.desc())
        if subject_id is not None:
            query = query.where(_SessionRow.subject_id == subject_id)
        with self._read() as session:
            return [_session(r) for r in session.scalars(query)]

    def get_session(self, session_id: int) -> schema.Session:
        with self._read() as session:
            return _session(self._get(session, _SessionRow, session_id))

    def set_session_state(self, session_id: int, state: schema.SessionState, node: str | None = None) -> schema.Session:
        """Move a session to ``state``; the first move to running / stopped stamps started / stopped_utc.
        ``node``: the process that runs it, stored with a move to running.

        Any move is accepted: which ones are allowed is the server's rule.
        """
        with self._write() as session:
            row = self._get(session, _SessionRow, session_id, for_update=True)
            row.state = state
            if state == "running" and node is not None:
                row.node = node
            if state == "running" and row.started_utc is None:
                row.started_utc = _stamp()
            elif state == "stopped" and row.stopped_utc is None:
                row.stopped_utc = _stamp()
            return _session(row)

    def set_session_settings(self, session_id: int, settings: schema.SessionSettings) -> schema.Session:
        with self._write() as session:
            row = self._get(session, _SessionRow, session_id, for_update=True)
            row.settings = settings.model_dump_json()
            return _session(row)

    def change_settings(
        self,
        session_id: int,
        settings: schema.SessionSettings,
        events: list[dict[str, Any]],
        *,
        trial_id: int | None = None,
    ) -> tuple[schema.Session, list[schema.Event]]:
        """Store new settings and their events (``add_event`` keyword arguments) in ONE transaction.

        The caller applies the change only after this returns: if it raises, nothing was stored and
        nothing must change.
        """
        with self._write() as session:
            row = self._get(session, _SessionRow, session_id, for_update=True)
            row.settings = settings.model_dump_json()
            rows = [self._event_row(session, session_id, trial_id, **e) for e in events]
            session.flush()
            return _session(row), [_event(r) for r in rows]

    def running_sessions(self, node: str | None = None) -> list[schema.Session]:
        """Sessions in state ``running``, oldest first (at start-up: those a crash left running); with ``node``,
        only those that node runs (and those of no node: made before sessions had one)."""
        query = select(_SessionRow).where(_SessionRow.state == "running").order_by(_SessionRow.id)
        if node is not None:
            query = query.where((_SessionRow.node == node) | _SessionRow.node.is_(None))
        with self._read() as session:
            return [_session(r) for r in session.scalars(query)]

    def running_per_node(self) -> dict[str, int]:
        """How many sessions each node runs (its ``running`` sessions), by node name."""
        query = (
            select(_SessionRow.node, func.count())
            .where(_SessionRow.state == "running", _SessionRow.node.is_not(None))
            .group_by(_SessionRow.node)
        )
        with self._read() as session:
            return {str(node): int(n) for node, n in session.execute(query)}

    # --- trials -----------------------------------------------------------------------------------

    def create_trial(
        self, session_id: int, name: str, path: str, status: schema.TrialStatus = "recording"
    ) -> schema.Trial:
        """A new trial of a session; ``path`` is its MCAP file relative to the data folder."""
        with self._write() as session:
            self._get(session, _SessionRow, session_id)
            row = _TrialRow(
                session_id=session_id,
                name=name,
                status=status,
                path=path,
                started_utc=_stamp(),
                samples=0,
                duration_s=0.0,
            )
            session.add(row)
            session.flush()
            return _trial(row)

    def finish_trial(self, trial_id: int, status: schema.TrialStatus, samples: int, duration_s: float) -> schema.Trial:
        """Record how a trial ended; stamps ``stopped_utc``."""
        with self._write() as session:
            row = self._get(session, _TrialRow, trial_id, for_update=True)
            row.status = status
            row.samples = samples
            row.duration_s = float(duration_s)
            row.stopped_utc = _stamp()
            return _trial(row)

    def create_upload_trial(
        self,
        subject_id: int,
        filename: str,
        path: str,
        samples: int,
        duration_s: float,
        *,
        before_commit: Callable[[], None] | None = None,
        sha256: str | None = None,
    ) -> schema.Trial:
        """An imported upload in ONE transaction: a stopped session (source ``upload`` with the file's
        ``sha256``, default settings) and its one trial (status ``uploaded``, ``path`` relative to the data folder).

        ``before_commit`` runs once both rows are written and validated, just before the commit: the
        caller moves the trial's file into place there. If anything raises (``before_commit`` too),
        nothing is stored.
        """
        with self._write() as session:
            self._get(session, _SubjectRow, subject_id)
            now = _stamp()
            source = schema.UploadSource(filename=filename, sha256=sha256)
            session_row = _SessionRow(
                subject_id=subject_id,
                source=source.model_dump_json(),
                settings=schema.SessionSettings().model_dump_json(),
                state="stopped",
                created_utc=now,
                stopped_utc=now,
            )
            session.add(session_row)
            session.flush()
            row = _TrialRow(
                session_id=session_row.id,
                name=filename,
                status="uploaded",
                path=path,
                started_utc=now,
                stopped_utc=now,
                samples=samples,
                duration_s=float(duration_s),
            )
            session.add(row)
            session.flush()
            _session(session_row)
            trial = _trial(row)
            if before_commit is not None:
                before_commit()
            return trial

    def find_upload(self, sha256: str) -> schema.Trial | None:
        """The first trial uploaded from a file whose SHA-256 is ``sha256`` (None: none; uploads from before the
        hash was kept are not found)."""
        source = schema.UploadSource(filename="x", sha256=sha256).model_dump_json()
        needle = source[source.index('"sha256"') :].rstrip("}")  # '"sha256":"<hex>"', as the column holds it
        query = (
            select(_TrialRow, _SessionRow.source)
            .join(_SessionRow, _SessionRow.id == _TrialRow.session_id)
            .where(_TrialRow.status == "uploaded", _SessionRow.source.contains(needle, autoescape=True))
            .order_by(_TrialRow.id)
        )
        with self._read() as session:
            for row, text in session.execute(query):
                found = schema.UploadSource.model_validate_json(text)
                if found.sha256 == sha256:
                    return _trial(row)
        return None

    def list_trials(self, session_id: int | None = None) -> list[schema.Trial]:
        """Trials in the order they were created; those of one session when ``session_id`` is given."""
        query = select(_TrialRow).order_by(_TrialRow.id)
        if session_id is not None:
            query = query.where(_TrialRow.session_id == session_id)
        with self._read() as session:
            return [_trial(r) for r in session.scalars(query)]

    def get_trial(self, trial_id: int) -> schema.Trial:
        with self._read() as session:
            return _trial(self._get(session, _TrialRow, trial_id))

    def trials_with_status(self, status: schema.TrialStatus) -> list[schema.Trial]:
        """Trials with ``status``, oldest first (at start-up: ``recording`` ones a crash left open)."""
        query = select(_TrialRow).where(_TrialRow.status == status).order_by(_TrialRow.id)
        with self._read() as session:
            return [_trial(r) for r in session.scalars(query)]

    # --- events -----------------------------------------------------------------------------------

    def add_event(
        self,
        session_id: int,
        *,
        t: float,
        kind: schema.EventKind,
        text: str,
        field: str | None = None,
        before: float | str | None = None,
        after: float | str | None = None,
        actor: str = "system",
        trial_id: int | None = None,
    ) -> schema.Event:
        """Log an event at session time ``t`` (s); stamps ``wall_utc`` to the millisecond.

        ``before`` / ``after`` read back exactly as given, numbers as floats. ``trial_id``, when
        given, must be a trial of this session (:class:`Conflict` otherwise).
        """
        with self._write() as session:
            row = self._event_row(
                session, session_id, trial_id, t=t, kind=kind, text=text, field=field, before=before, after=after,
                actor=actor,
            )  # fmt: skip
            session.flush()
            return _event(row)

    def _event_row(
        self,
        session: orm.Session,
        session_id: int,
        trial_id: int | None,
        *,
        t: float,
        kind: schema.EventKind,
        text: str,
        field: str | None = None,
        before: float | str | None = None,
        after: float | str | None = None,
        actor: str = "system",
    ) -> _EventRow:
        """Add an event row inside an open write transaction (checks session and trial)."""
        self._get(session, _SessionRow, session_id)
        if trial_id is not None:
            trial = self._get(session, _TrialRow, trial_id)
            if trial.session_id != session_id:
                raise Conflict(f"trial {trial_id} belongs to session {trial.session_id}, not {session_id}")
        row = _EventRow(
            session_id=session_id,
            trial_id=trial_id,
            t=float(t),
            wall_utc=_now().isoformat(timespec="milliseconds"),
            kind=kind,
            text=text,
            field=field,
            before=_encode_value(before),
            after=_encode_value(after),
            actor=actor,
        )
        session.add(row)
        return row

    def list_events(self, session_id: int) -> list[schema.Event]:
        """A session's events, oldest first (by ``t``, then by insertion)."""
        with self._read() as session:
            self._get(session, _SessionRow, session_id)
            return self._events(session, _EventRow.session_id == session_id)

    def trial_events(self, trial_id: int) -> list[schema.Event]:
        """The events logged with ``trial_id``, oldest first."""
        with self._read() as session:
            self._get(session, _TrialRow, trial_id)
            return self._events(session, _EventRow.trial_id == trial_id)

    @staticmethod
    def _events(session: orm.Session, where: ColumnElement[bool]) -> list[schema.Event]:
        query = select(_EventRow).where(where).order_by(_EventRow.t, _EventRow.id)
        return [_event(r) for r in session.scalars(query)]

    # --- personalized gait models (seed 004 fingerprints) -----------------------------------------

    def add_personalization(self, p: schema.Personalization) -> schema.Personalization:
        """Store ``p`` as a new ``candidate`` version of its subject (its ``id``, ``version``, ``state`` and
        ``created_utc`` are assigned here); :class:`NotFound` for an unknown subject or trial."""
        with self._write() as session:
            self._get(session, _SubjectRow, p.subject_id)
            if p.source_trial_id is not None:
                self._get(session, _TrialRow, p.source_trial_id)
            last = session.scalar(
                select(_PersonalizationRow.version)
                .where(_PersonalizationRow.subject_id == p.subject_id)
                .order_by(_PersonalizationRow.version.desc())
                .limit(1)
            )
            fields = p.model_dump(exclude={"id", "fingerprint", "excluded", "version", "state", "created_utc"})
            row = _PersonalizationRow(
                **fields,
                fingerprint=json.dumps(p.fingerprint),
                excluded=json.dumps(p.excluded),
                version=(last or 0) + 1,
                state="candidate",
                created_utc=_stamp(),
                replaced_id=None,
            )
            session.add(row)
            session.flush()
            return _personalization(row)

    def list_personalizations(self, subject_id: int, model: str | None = None) -> list[schema.Personalization]:
        """The subject's personalizations (of ``model``, else of every model), newest first."""
        with self._read() as session:
            self._get(session, _SubjectRow, subject_id)
            q = select(_PersonalizationRow).where(_PersonalizationRow.subject_id == subject_id)
            if model is not None:
                q = q.where(_PersonalizationRow.model == model)
            return [_personalization(r) for r in session.scalars(q.order_by(_PersonalizationRow.id.desc()))]

    def get_personalization(self, personalization_id: int) -> schema.Personalization:
        with self._read() as session:
            return _personalization(self._get(session, _PersonalizationRow, personalization_id))

    def active_personalization(self, subject_id: int, model: str) -> schema.Personalization | None:
        """The subject's active personalization of ``model`` (what ``fp_ls`` runs), None when there is none."""
        with self._read() as session:
            row = self._active_row(session, subject_id, model)
            return None if row is None else _personalization(row)

    def promote_personalization(self, personalization_id: int, actor: str) -> schema.Personalization:
        """Make it the subject's active one for its model (the one active before is retired and remembered,
        so that :meth:`rollback_personalization` can bring it back). Promoting the active one changes nothing."""
        with self._write() as session:
            row = self._get(session, _PersonalizationRow, personalization_id, for_update=True)
            if row.state == "active":
                return _personalization(row)
            current = self._active_row(session, row.subject_id, row.model)
            if current is not None:
                current.state, current.retired_utc, current.retired_by = "retired", _stamp(), actor
            row.state, row.replaced_id = "active", None if current is None else current.id
            row.promoted_utc, row.promoted_by = _stamp(), actor
            session.flush()
            return _personalization(row)

    def rollback_personalization(
        self, subject_id: int, model: str, actor: str
    ) -> tuple[schema.Personalization, schema.Personalization | None]:
        """Retire the active personalization and make the one it replaced active again (none: the average
        model). Returns ``(rolled back, now active)``; :class:`Conflict` when nothing is active."""
        with self._write() as session:
            self._get(session, _SubjectRow, subject_id)
            current = self._active_row(session, subject_id, model)
            if current is None:
                raise Conflict(f"subject {subject_id} has no active personalization of model {model!r} to roll back")
            current.state, current.retired_utc, current.retired_by = "retired", _stamp(), actor
            back = None if current.replaced_id is None else session.get(_PersonalizationRow, current.replaced_id)
            if back is not None:
                back.state, back.promoted_utc, back.promoted_by = "active", _stamp(), actor
                back.retired_utc = back.retired_by = None
            session.flush()
            return _personalization(current), None if back is None else _personalization(back)

    @staticmethod
    def _active_row(session: orm.Session, subject_id: int, model: str) -> _PersonalizationRow | None:
        return session.scalars(
            select(_PersonalizationRow).where(
                _PersonalizationRow.subject_id == subject_id,
                _PersonalizationRow.model == model,
                _PersonalizationRow.state == "active",
            )
        ).first()

    # --- IMU mounting calibrations ----------------------------------------------------------------

    def add_imu_calibration(self, cal: schema.ImuCalibration) -> schema.ImuCalibration:
        """Store an accepted calibration (its ``id`` and ``created_utc`` are assigned here): the subject's
        current one from now on. :class:`Conflict` for a refused one; :class:`NotFound` for an unknown
        subject, session or trial."""
        if not cal.ok:
            raise Conflict("a refused IMU calibration is not stored")
        with self._write() as session:
            self._get(session, _SubjectRow, cal.subject_id)
            self._get(session, _SessionRow, cal.session_id)
            if cal.trial_id is not None:
                self._get(session, _TrialRow, cal.trial_id)
            row = _ImuCalibrationRow(
                **cal.model_dump(include={"subject_id", "session_id", "trial_id", "duration_s", "created_by", "note"}),
                sensors=_IMU_SENSORS.dump_json(cal.sensors).decode(),
                created_utc=_stamp(),
            )
            session.add(row)
            session.flush()
            return _imu_calibration(row)

    def list_imu_calibrations(
        self, subject_id: int | None = None, session_id: int | None = None
    ) -> list[schema.ImuCalibration]:
        """Stored calibrations (of a subject, of a session, or both), newest first."""
        with self._read() as session:
            q = select(_ImuCalibrationRow)
            if subject_id is not None:
                self._get(session, _SubjectRow, subject_id)
                q = q.where(_ImuCalibrationRow.subject_id == subject_id)
            if session_id is not None:
                self._get(session, _SessionRow, session_id)
                q = q.where(_ImuCalibrationRow.session_id == session_id)
            return [_imu_calibration(r) for r in session.scalars(q.order_by(_ImuCalibrationRow.id.desc()))]

    def current_imu_calibration(self, subject_id: int) -> schema.ImuCalibration | None:
        """The subject's latest accepted calibration (what their next session applies), None when none."""
        with self._read() as session:
            row = session.scalars(
                select(_ImuCalibrationRow)
                .where(_ImuCalibrationRow.subject_id == subject_id)
                .order_by(_ImuCalibrationRow.id.desc())
                .limit(1)
            ).first()
            return None if row is None else _imu_calibration(row)

    # --- review annotations (issue #12; a note at a time or over a span of a trial) ----------------------

    def add_review_annotation(self, trial_id: int, body: schema.ReviewAnnotationCreate) -> schema.ReviewAnnotation:
        """Save a note added in review with trial ``trial_id`` (:class:`NotFound` if there is no such trial)."""
        with self._write() as session:
            self._get(session, _TrialRow, trial_id)
            row = _ReviewAnnotationRow(
                trial_id=trial_id, t=float(body.t), t_end=None if body.t_end is None else float(body.t_end),
                text=body.text, actor=body.actor, created_utc=_stamp(),
            )  # fmt: skip
            session.add(row)
            session.flush()
            return _review_annotation(row)

    def list_review_annotations(self, trial_id: int) -> list[schema.ReviewAnnotation]:
        """A trial's review notes, by time (then by when they were added)."""
        with self._read() as session:
            self._get(session, _TrialRow, trial_id)
            q = select(_ReviewAnnotationRow).where(_ReviewAnnotationRow.trial_id == trial_id)
            q = q.order_by(_ReviewAnnotationRow.t, _ReviewAnnotationRow.id)
            return [_review_annotation(r) for r in session.scalars(q)]

    def trial_notes(self, trial_id: int) -> list[schema.ReviewAnnotation]:
        """A trial's notes by time: those added in review and those taken live while it recorded (the session's
        ``annotation`` events logged with the trial, ``source`` ``live``, their ids the events')."""
        with self._read() as session:
            self._get(session, _TrialRow, trial_id)
            q = select(_ReviewAnnotationRow).where(_ReviewAnnotationRow.trial_id == trial_id)
            notes = [_review_annotation(r) for r in session.scalars(q)]
            live = select(_EventRow).where(_EventRow.trial_id == trial_id, _EventRow.kind == "annotation")
            notes += [_live_note(r, trial_id) for r in session.scalars(live) if r.text.strip() and r.actor.strip()]
        return sorted(notes, key=lambda n: (n.t, n.source == "review", n.id))

    def delete_review_annotation(self, trial_id: int, annotation_id: int, actor: str) -> None:
        """Delete a trial's review note. Only whoever wrote it may (:class:`NotAllowed` for anyone else);
        :class:`NotFound` if the trial has no such note."""
        with self._write() as session:
            self._get(session, _TrialRow, trial_id)
            row = session.get(_ReviewAnnotationRow, annotation_id) if 0 < annotation_id <= schema.INT64_MAX else None
            if row is None or row.trial_id != trial_id:
                raise NotFound(f"trial {trial_id} has no note {annotation_id}")
            if row.actor != actor:
                raise NotAllowed(f"note {annotation_id} was written by {row.actor}: only they may delete it")
            session.delete(row)


class NotAllowed(PermissionError):
    """The action is not this actor's to take (a review note deleted by someone other than its author)."""


class _ReviewAnnotationRow(_Base):
    __tablename__ = "review_annotations"

    id: Mapped[int] = mapped_column(primary_key=True)
    trial_id: Mapped[int] = mapped_column(ForeignKey("trials.id"), index=True)
    t: Mapped[float]
    t_end: Mapped[float | None]
    text: Mapped[str] = mapped_column(Text)
    actor: Mapped[str] = mapped_column(String(64))
    created_utc: Mapped[str] = mapped_column(String(40))


def _review_annotation(row: _ReviewAnnotationRow) -> schema.ReviewAnnotation:
    return schema.ReviewAnnotation.model_validate(row, from_attributes=True)


def _live_note(row: _EventRow, trial_id: int) -> schema.ReviewAnnotation:
    """A note taken live (an ``annotation`` event of the trial) as one of the trial's notes."""
    return schema.ReviewAnnotation(
        id=row.id, trial_id=trial_id, t=max(0.0, row.t), text=row.text[:500], actor=row.actor, created_utc=row.wall_utc,
        source="live",
    )  # fmt: skip

"""The Alembic migrations (``sessions/migrations``): up, down and up again on SQLite and PostgreSQL, a
database made before migrations upgraded in place with its rows kept, two processes opening one new
database, the models matching the migrations, and ``gaitscope db``.

PostgreSQL runs when ``GAITSCOPE_TEST_POSTGRES`` names a server (``scripts/postgres.sh``); without it
those cases are skipped, with the reason.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import Connection, create_engine, inspect, make_url
from sqlalchemy.pool import NullPool

from gaitscope.server.cli import main
from gaitscope.sessions import migrations, schema
from gaitscope.sessions.store import Store, all_metadata, make_engine, write_transaction

POSTGRES = os.environ.get("GAITSCOPE_TEST_POSTGRES", "")
NO_POSTGRES = "GAITSCOPE_TEST_POSTGRES is not set (bash scripts/postgres.sh .venv/bin/python -m pytest ...)"
BACKENDS = [
    "sqlite",
    pytest.param("postgresql", marks=pytest.mark.skipif(not POSTGRES, reason=NO_POSTGRES)),
]
#: Every table the migrations make: the baseline's and those of later revisions (their modules' tables).
TABLES = set(all_metadata().tables)


@contextlib.contextmanager
def _empty_postgres() -> Iterator[str]:
    """A new, empty PostgreSQL database (from ``template0``: no tables at all); dropped afterwards."""
    admin = create_engine(make_url(POSTGRES).set(database="postgres"), isolation_level="AUTOCOMMIT", poolclass=NullPool)
    name = f"gaitscope_empty_{uuid.uuid4().hex[:12]}"
    with admin.connect() as c:
        c.exec_driver_sql(f'CREATE DATABASE "{name}" TEMPLATE template0')
    try:
        yield make_url(POSTGRES).set(database=name).render_as_string(hide_password=False)
    finally:
        with admin.connect() as c:
            c.exec_driver_sql(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
        admin.dispose()


@pytest.fixture(params=BACKENDS)
def empty_url(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[str]:
    """An empty database: a SQLite file that does not exist yet, or a new PostgreSQL database."""
    if request.param == "sqlite":
        yield f"sqlite:///{(tmp_path / 'db' / 'gaitscope.db').as_posix()}"
    else:
        with _empty_postgres() as url:
            yield url


def _tables(url: str) -> set[str]:
    engine = make_engine(url)
    try:
        with engine.connect() as c:
            return set(inspect(c).get_table_names())
    finally:
        engine.dispose()


def _versions(url: str) -> tuple[str, ...]:
    engine = make_engine(url)
    try:
        with engine.connect() as c:
            return migrations.current(c)
    finally:
        engine.dispose()


def _diffs(connection: Connection) -> list[object]:
    context = MigrationContext.configure(connection, opts={"compare_type": True})
    return list(compare_metadata(context, all_metadata()))


HEADS = tuple(migrations.script_directory().get_heads())


# --- up, down, up -----------------------------------------------------------------------------------


def test_a_new_database_is_migrated_to_head_and_down_to_base_and_up_again(empty_url: str) -> None:
    assert _tables(empty_url) == set()
    store = Store(empty_url)
    subject = store.create_subject(schema.SubjectCreate(code="M01", leg_length_m=0.9, mass_kg=70.0))
    store.close()
    assert _versions(empty_url) == HEADS
    assert _tables(empty_url) == TABLES | {"alembic_version"}

    engine = make_engine(empty_url)
    try:
        with write_transaction(engine) as c:
            migrations.run(c, "base", downgrade=True)
        assert _tables(empty_url) == {"alembic_version"}  # every table gone; Alembic keeps its own, empty
        assert _versions(empty_url) == ()
        with write_transaction(engine) as c:
            migrations.run(c, migrations.BASELINE)  # one revision at a time works too
        assert _versions(empty_url) == (migrations.BASELINE,)
        assert _tables(empty_url) == set(migrations.BASELINE_TABLES) | {"alembic_version"}
    finally:
        engine.dispose()

    again = Store(empty_url)  # the rest of the way up, as the server does it
    try:
        assert _versions(empty_url) == HEADS
        assert again.list_subjects() == []  # the downgrade dropped the rows with the tables
        assert again.create_subject(schema.SubjectCreate(code="M01", leg_length_m=0.9, mass_kg=70.0)).id == subject.id
    finally:
        again.close()


def test_the_migrations_make_what_the_models_declare(empty_url: str) -> None:
    # Fails while a module declares tables (gaitscope.sessions.accounts.tables, gaitscope.sessions.audit.tables) that no
    # revision creates yet: each new table or column needs its revision.
    Store(empty_url).close()
    engine = make_engine(empty_url)
    try:
        with engine.connect() as c:
            assert _diffs(c) == []
    finally:
        engine.dispose()


def test_ids_are_64_bit_on_both_databases(empty_url: str) -> None:
    store = Store(empty_url)
    try:
        big = schema.INT64_MAX
        subject = store.create_subject(schema.SubjectCreate(code="B01", leg_length_m=0.9, mass_kg=70.0))
        with store.writing() as session:  # what the API admits as an id, the database holds
            session.connection().exec_driver_sql(f"UPDATE subjects SET id = {big} WHERE id = {subject.id}")
        assert store.get_subject(big).code == "B01"
    finally:
        store.close()


# --- a database made before migrations ------------------------------------------------------------

#: The tables as the store made them with ``create_all`` before migrations (SQLite's DDL, verbatim).
#: Only SQLite databases predate the migrations: no PostgreSQL driver shipped before them.
LEGACY_SQLITE = [
    """CREATE TABLE subjects (id INTEGER NOT NULL, code VARCHAR(32) NOT NULL, leg_length_m DOUBLE NOT NULL,
    mass_kg DOUBLE NOT NULL, side VARCHAR(8) NOT NULL, notes TEXT NOT NULL, created_utc VARCHAR(40) NOT NULL,
    PRIMARY KEY (id), UNIQUE (code))""",
    """CREATE TABLE sessions (id INTEGER NOT NULL, subject_id INTEGER NOT NULL, source TEXT NOT NULL,
    settings TEXT NOT NULL, state VARCHAR(16) NOT NULL, created_utc VARCHAR(40) NOT NULL, started_utc VARCHAR(40),
    stopped_utc VARCHAR(40), PRIMARY KEY (id), FOREIGN KEY(subject_id) REFERENCES subjects (id))""",
    "CREATE INDEX ix_sessions_subject_id ON sessions (subject_id)",
    "CREATE INDEX ix_sessions_state ON sessions (state)",
    """CREATE TABLE trials (id INTEGER NOT NULL, session_id INTEGER NOT NULL, name TEXT NOT NULL,
    status VARCHAR(16) NOT NULL, path TEXT NOT NULL, started_utc VARCHAR(40) NOT NULL, stopped_utc VARCHAR(40),
    samples INTEGER NOT NULL, duration_s DOUBLE NOT NULL, PRIMARY KEY (id),
    FOREIGN KEY(session_id) REFERENCES sessions (id))""",
    "CREATE INDEX ix_trials_status ON trials (status)",
    "CREATE INDEX ix_trials_session_id ON trials (session_id)",
    """CREATE TABLE events (id INTEGER NOT NULL, session_id INTEGER NOT NULL, trial_id INTEGER, t DOUBLE NOT NULL,
    wall_utc VARCHAR(40) NOT NULL, kind VARCHAR(16) NOT NULL, text TEXT NOT NULL, field VARCHAR(64), "before" TEXT,
    "after" TEXT, actor VARCHAR(64) NOT NULL, PRIMARY KEY (id), FOREIGN KEY(session_id) REFERENCES sessions (id),
    FOREIGN KEY(trial_id) REFERENCES trials (id))""",
    "CREATE INDEX ix_events_trial_id ON events (trial_id)",
    "CREATE INDEX ix_events_session_t ON events (session_id, t)",
    """CREATE TABLE imu_calibrations (id INTEGER NOT NULL, subject_id INTEGER NOT NULL, session_id INTEGER NOT NULL,
    trial_id INTEGER, duration_s DOUBLE NOT NULL, sensors TEXT NOT NULL, created_utc VARCHAR(40) NOT NULL,
    created_by VARCHAR(64) NOT NULL, note TEXT NOT NULL, PRIMARY KEY (id),
    FOREIGN KEY(subject_id) REFERENCES subjects (id), FOREIGN KEY(session_id) REFERENCES sessions (id),
    FOREIGN KEY(trial_id) REFERENCES trials (id))""",
    "CREATE INDEX ix_imu_calibrations_subject_id ON imu_calibrations (subject_id)",
    "CREATE INDEX ix_imu_calibrations_session_id ON imu_calibrations (session_id)",
    """CREATE TABLE personalizations (id INTEGER NOT NULL, subject_id INTEGER NOT NULL, version INTEGER NOT NULL,
    model VARCHAR(32) NOT NULL, fingerprint TEXT NOT NULL, fit_rmse_avg_deg DOUBLE NOT NULL,
    fit_rmse_personal_deg DOUBLE NOT NULL, source_trial_id INTEGER, strides_used INTEGER NOT NULL,
    strides_excluded INTEGER NOT NULL, seconds_used DOUBLE NOT NULL, excluded TEXT NOT NULL,
    stride_length_source VARCHAR(64) NOT NULL, state VARCHAR(16) NOT NULL, created_utc VARCHAR(40) NOT NULL,
    created_by VARCHAR(64) NOT NULL, promoted_utc VARCHAR(40), promoted_by VARCHAR(64), retired_utc VARCHAR(40),
    retired_by VARCHAR(64), replaced_id INTEGER, note TEXT NOT NULL, PRIMARY KEY (id),
    FOREIGN KEY(subject_id) REFERENCES subjects (id), FOREIGN KEY(source_trial_id) REFERENCES trials (id))""",
    "CREATE INDEX ix_personalizations_subject_model ON personalizations (subject_id, model)",
    """CREATE TABLE review_annotations (id INTEGER NOT NULL, trial_id INTEGER NOT NULL, t DOUBLE NOT NULL,
    t_end DOUBLE, text TEXT NOT NULL, actor VARCHAR(64) NOT NULL, created_utc VARCHAR(40) NOT NULL,
    PRIMARY KEY (id), FOREIGN KEY(trial_id) REFERENCES trials (id))""",
    "CREATE INDEX ix_review_annotations_trial_id ON review_annotations (trial_id)",
]
LEGACY_ROWS = [
    "INSERT INTO subjects VALUES (1, 'OLD01', 0.91, 72.5, 'left', 'kept', '2025-01-02T03:04:05+00:00')",
    """INSERT INTO sessions VALUES (1, 1, '{"kind": "device"}', '{}', 'stopped', '2025-01-02T03:05:00+00:00',
    '2025-01-02T03:05:01+00:00', '2025-01-02T03:15:00+00:00')""",
    """INSERT INTO trials VALUES (1, 1, 'walk', 'finished', 'recordings/1/walk.mcap', '2025-01-02T03:06:00+00:00',
    '2025-01-02T03:07:00+00:00', 12000, 60.0)""",
    """INSERT INTO events VALUES (1, 1, 1, 2.5, '2025-01-02T03:06:02.500+00:00', 'setting', 'torque gain 1 -> 1.2',
    'torque_gain', '1.0', '"default"', 'clinician')""",
]


def _legacy_sqlite(path: Path, statements: list[str]) -> str:
    url = f"sqlite:///{path.as_posix()}"
    engine = create_engine(url, poolclass=NullPool)
    with engine.begin() as c:
        for statement in statements:
            c.exec_driver_sql(statement)
    engine.dispose()
    return url


def test_a_database_made_before_migrations_is_upgraded_in_place_with_its_rows(tmp_path: Path) -> None:
    url = _legacy_sqlite(tmp_path / "old.db", LEGACY_SQLITE + LEGACY_ROWS)
    assert _versions(url) == ()
    store = Store(url)
    try:
        assert _versions(url) == HEADS
        [subject] = store.list_subjects()
        assert (subject.id, subject.code, subject.side, subject.notes) == (1, "OLD01", "left", "kept")
        [session] = store.list_sessions()
        assert (session.id, session.subject_id, session.state, session.source.kind) == (1, 1, "stopped", "device")
        [trial] = store.list_trials()
        assert (trial.id, trial.path, trial.samples, trial.duration_s) == (1, "recordings/1/walk.mcap", 12000, 60.0)
        [event] = store.list_events(1)
        assert (event.field, event.before, event.after, event.actor) == ("torque_gain", 1.0, "default", "clinician")
        assert store.create_subject(schema.SubjectCreate(code="NEW01", leg_length_m=0.9, mass_kg=70.0)).id == 2
    finally:
        store.close()
    assert _tables(url) == TABLES | {"alembic_version"}
    engine = make_engine(url)
    try:
        with engine.connect() as c:
            assert _diffs(c) == []  # in place, it ends exactly where a new database does
    finally:
        engine.dispose()


def test_a_database_from_before_review_notes_gets_the_missing_table(tmp_path: Path) -> None:
    # Older still: made before issue #12 added review notes. The baseline adds just what is missing.
    older = [s for s in LEGACY_SQLITE if "review_annotations" not in s]
    url = _legacy_sqlite(tmp_path / "older.db", older + LEGACY_ROWS)
    store = Store(url)
    try:
        assert _versions(url) == HEADS
        assert [s.code for s in store.list_subjects()] == ["OLD01"]
        assert store.list_review_annotations(1) == []
    finally:
        store.close()
    assert "review_annotations" in _tables(url)


# --- two processes, one new database ----------------------------------------------------------------

_OPEN = """
import sys
from gaitscope.sessions import schema
from gaitscope.sessions.store import Store
store = Store(sys.argv[1])
store.create_subject(schema.SubjectCreate(code=sys.argv[2], leg_length_m=0.9, mass_kg=70.0))
store.close()
"""


def test_two_processes_opening_one_new_database_both_succeed(empty_url: str) -> None:
    # Each migrates under the database's write lock: one creates the tables, the other finds them at head.
    procs = [
        subprocess.Popen([sys.executable, "-c", _OPEN, empty_url, f"P{k}"], stderr=subprocess.PIPE)
        for k in range(2)
    ]  # fmt: skip
    errors = []
    for p in procs:
        with p:  # its pipe closed whatever happens (an unclosed one fails the next test as a warning)
            _, err = p.communicate(timeout=120)
        errors.append((p.returncode, err.decode()[-2000:]))
    assert [code for code, _ in errors] == [0, 0], errors
    assert _versions(empty_url) == HEADS
    store = Store(empty_url)
    try:
        assert sorted(s.code for s in store.list_subjects()) == ["P0", "P1"]
    finally:
        store.close()


def test_an_in_memory_database_is_migrated_on_its_one_connection() -> None:
    store = Store("sqlite://")
    try:
        with store.reading() as session:
            connection = session.connection()
            assert migrations.current(connection) == HEADS
            assert set(inspect(connection).get_table_names()) == TABLES | {"alembic_version"}
    finally:
        store.close()


# --- gaitscope db ----------------------------------------------------------------------------------


def test_the_db_command_upgrades_downgrades_and_reports(empty_url: str, capsys: pytest.CaptureFixture[str]) -> None:
    shown = make_url(empty_url).render_as_string(hide_password=True)
    assert main(["db", "--database-url", empty_url, "current"]) == 0
    assert capsys.readouterr().out == "base (unversioned)\n"
    assert main(["db", "--database-url", empty_url, "upgrade"]) == 0
    assert capsys.readouterr().out == f"{shown}: at {', '.join(HEADS)}\n"
    assert main(["db", "--database-url", empty_url, "current"]) == 0
    assert capsys.readouterr().out == "".join(f"{h} (head, current)\n" for h in HEADS)
    assert main(["db", "--database-url", empty_url, "history"]) == 0
    history = capsys.readouterr().out.splitlines()
    assert (
        history[-1] == f"{migrations.BASELINE}{' (head, current)' if HEADS == (migrations.BASELINE,) else ''}  "
        "Baseline: the tables as they were before migrations."
    )
    assert len(history) == len(list(migrations.script_directory().walk_revisions()))
    assert main(["db", "--database-url", empty_url, "downgrade", "base"]) == 0
    assert capsys.readouterr().out == f"{shown}: at base\n"
    assert _tables(empty_url) == {"alembic_version"}


def test_the_db_command_names_the_database_on_an_unknown_revision(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    url = f"sqlite:///{(tmp_path / 'x.db').as_posix()}"
    assert main(["db", "--database-url", url, "upgrade", "nope"]) == 2
    err = capsys.readouterr().err
    assert err == f"gaitscope: error: database {url}: Can't locate revision identified by 'nope'\n"


def test_the_db_command_takes_the_url_from_the_environment(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    url = f"sqlite:///{(tmp_path / 'env.db').as_posix()}"
    monkeypatch.setenv("GAITSCOPE_DATABASE_URL", url)
    assert main(["db", "upgrade"]) == 0
    assert capsys.readouterr().out == f"{url}: at {', '.join(HEADS)}\n"
    assert _versions(url) == HEADS

"""Shared fixtures: a small virtual cohort and models trained on it (built once per test run), and the
real app with a real SQLite file in a temporary folder.

With ``GAITSCOPE_TEST_POSTGRES`` set (``scripts/postgres.sh`` sets it to a throwaway server's template
database) every test module and every test gets a fresh PostgreSQL database copied from the migrated
template, named in ``GAITSCOPE_DATABASE_URL`` for as long as it runs: :class:`Settings` and the server
processes the tests start use it instead of the data folder's SQLite file. ``database_url`` is that
database, or a SQLite file in the test's temporary folder when no PostgreSQL is given.
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import os
import time
from collections.abc import Iterator
from pathlib import Path

import pandas as pd
import pytest
import sqlalchemy.exc
from fastapi.testclient import TestClient
from sqlalchemy import Engine, create_engine, make_url
from sqlalchemy.pool import NullPool

from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.server.app import create_app
from gaitscope.server.settings import Settings
from gaitscope.sessions.offline.training import StrideData, fit_models, stride_data
from gaitscope.sessions.synth.cohort import CohortSpec, generate_cohort

SMALL = CohortSpec(n_subjects=3, strides_per_condition=3)


@pytest.fixture(scope="session")
def small_cohort() -> pd.DataFrame:
    return generate_cohort(SMALL)


@pytest.fixture(scope="session")
def small_data(small_cohort: pd.DataFrame) -> StrideData:
    return stride_data(small_cohort)


@pytest.fixture(scope="session")
def small_model(small_data: StrideData) -> TrainedModel:
    return fit_models(small_data)


@pytest.fixture
def client(tmp_path: Path) -> Iterator[TestClient]:
    """The app (lifespan included) on a fresh data folder: no demo, no leg view, small upload limits.

    TestClient sends ``Host: testserver``: allowed here, and only here (never by default). The disk
    thresholds are 1 MiB so that the tests do not depend on how full the machine's disk is."""
    settings = Settings(
        data_dir=tmp_path / "data", demo=False, leg_view=False, max_upload_mb=8, upload_chunk_kb=64,
        allowed_hosts=["testserver"], disk_warn_mb=1, disk_stop_mb=1, upload_min_free_mb=1,
        gp_fit_duty=1.0,  # the tests stream faster than real time: every window fitted as it comes
    )  # fmt: skip
    with TestClient(create_app(settings)) as c:
        yield c


# --- the database: SQLite by default, PostgreSQL when GAITSCOPE_TEST_POSTGRES names a template ----------

#: The template database's URL (``postgresql+psycopg://user@host:port/template``), or "" for SQLite.
POSTGRES = os.environ.get("GAITSCOPE_TEST_POSTGRES", "")
#: Tests that never open a database (house rule 1: the estimators do no I/O) get no PostgreSQL copy.
_NO_DATABASE = Path(__file__).parent / "estimators"
_names = itertools.count(1)


def _admin_engine() -> Engine:
    """An autocommit connection to the server's ``postgres`` database (CREATE / DROP DATABASE)."""
    return create_engine(make_url(POSTGRES).set(database="postgres"), isolation_level="AUTOCOMMIT", poolclass=NullPool)


@pytest.fixture(scope="session")
def _postgres_template() -> Iterator[Engine | None]:
    """The template database made afresh and migrated to head once per run; yields the admin engine."""
    if not POSTGRES:
        yield None
        return
    from gaitscope.sessions.store import Store

    template = make_url(POSTGRES).database
    admin = _admin_engine()
    with admin.connect() as c:
        c.exec_driver_sql(f'DROP DATABASE IF EXISTS "{template}" WITH (FORCE)')
        c.exec_driver_sql(f'CREATE DATABASE "{template}"')
    Store(POSTGRES).close()  # the migrations, once; no connection may stay open on a template
    yield admin
    admin.dispose()


@contextlib.contextmanager
def _postgres_copy(admin: Engine, kind: str) -> Iterator[str]:
    """A new database copied from the template (about 0.2 s on this machine); its URL. Dropped afterwards
    with any connection a test left open (``WITH (FORCE)``, PostgreSQL 13 and later)."""
    name = f"gaitscope_{kind}_{os.getpid()}_{next(_names)}"
    template = make_url(POSTGRES).database
    with admin.connect() as c:
        c.exec_driver_sql(f'CREATE DATABASE "{name}" TEMPLATE "{template}"')
    try:
        yield make_url(POSTGRES).set(database=name).render_as_string(hide_password=False)
    finally:
        _drop(admin, name)


def _drop(admin: Engine, name: str, tries: int = 5) -> None:
    """Drop a test's database. ``WITH (FORCE)`` may be refused while one of its connections belongs to a
    process of another role (a server subprocess's worker ending as it is asked): try again shortly; the
    throwaway cluster, and any database left in it, is deleted when the run ends anyway."""
    for attempt in range(tries):
        try:
            with admin.connect() as c:
                c.exec_driver_sql(f'DROP DATABASE IF EXISTS "{name}" WITH (FORCE)')
            return
        except sqlalchemy.exc.DBAPIError:
            if attempt == tries - 1:
                logging.getLogger(__name__).warning("test database %s not dropped (deleted with the cluster)", name)
                return
            time.sleep(0.5)


@pytest.fixture(scope="module", autouse=True)
def _postgres_module_database(request: pytest.FixtureRequest, _postgres_template: Engine | None) -> Iterator[None]:
    """PostgreSQL: one database for the module's module-scoped fixtures (apps and servers started once)."""
    if _postgres_template is None or request.path.is_relative_to(_NO_DATABASE):
        yield
        return
    with _postgres_copy(_postgres_template, "m") as url, pytest.MonkeyPatch.context() as mp:
        mp.setenv("GAITSCOPE_DATABASE_URL", url)
        yield


@pytest.fixture(autouse=True)
def _postgres_test_database(
    request: pytest.FixtureRequest, _postgres_template: Engine | None, monkeypatch: pytest.MonkeyPatch
) -> Iterator[str | None]:
    """PostgreSQL: a fresh database for each test, in ``GAITSCOPE_DATABASE_URL`` while it runs."""
    if _postgres_template is None or request.path.is_relative_to(_NO_DATABASE):
        yield None
        return
    with _postgres_copy(_postgres_template, "t") as url:
        monkeypatch.setenv("GAITSCOPE_DATABASE_URL", url)
        yield url


@pytest.fixture
def database_url(_postgres_test_database: str | None, tmp_path: Path) -> str:
    """The test's own empty database (migrated): PostgreSQL when given, else a SQLite file in ``tmp_path``."""
    return _postgres_test_database or f"sqlite:///{(tmp_path / 'gaitscope.db').as_posix()}"

"""Shared fixtures: a small virtual cohort and models trained on it (built once per test run), and the
real app with a real SQLite file in a temporary folder."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pandas as pd
import pytest
from fastapi.testclient import TestClient

from estimators.pipeline import TrainedModel
from server.app import create_app
from server.settings import Settings
from sessions.offline.training import StrideData, fit_models, stride_data
from sessions.synth.cohort import CohortSpec, generate_cohort

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
        data_dir=tmp_path / "data", demo=False, leg_view=False, max_upload_mb=5, upload_chunk_kb=64,
        allowed_hosts=["testserver"], disk_warn_mb=1, disk_stop_mb=1, upload_min_free_mb=1,
        gp_fit_duty=1.0,  # the tests stream faster than real time: every window fitted as it comes
    )  # fmt: skip
    with TestClient(create_app(settings)) as c:
        yield c

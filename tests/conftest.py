"""Shared fixtures: a small virtual cohort and models trained on it (built once per test run)."""

from __future__ import annotations

import pandas as pd
import pytest

from estimators.pipeline import TrainedModel
from sessions.cohort import CohortSpec, generate_cohort
from sessions.training import StrideData, fit_models, stride_data

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

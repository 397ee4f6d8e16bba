"""Property-based invariants of the filters under arbitrary measurement sequences and time steps.

After every sample: the EKF's (and the backup's) covariance is symmetric positive semi-definite, the
phases lie in [0, 1), the state is finite, and the torque is a finite number within its bounds (no
NaN reaches it). The bare :class:`PhaseEKF` is driven with physically plausible measurements (what
the pipeline's screening lets through); the whole :class:`GaitStatePipeline` with anything at all.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gaitscope.estimators.phase_ekf import PhaseEKF
from gaitscope.estimators.pipeline import CHANNEL_LIMITS, GaitStatePipeline, PipelineConfig, TrainedModel
from gaitscope.sessions.formats.models import default_model_path, load_model

MAX_TORQUE = 30.0
PROPERTY = settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])

#: A time step: typical, jittered, tiny, or long enough to restart the pipeline.
DT = st.one_of(st.just(0.01), st.floats(1e-6, 0.05), st.floats(0.05, 3.0))
#: One measurement channel within its plausible range, or missing.
PLAUSIBLE = [st.one_of(st.floats(lo, hi), st.just(math.nan)) for lo, hi in CHANNEL_LIMITS]
#: Anything a float can be.
ANY = st.one_of(st.floats(), st.floats(-200.0, 200.0), st.sampled_from([0.0, 1e308, -1e308, 5e-324]))


@pytest.fixture(scope="module")
def model() -> TrainedModel:
    return load_model(default_model_path())[0]


def _assert_psd(P: np.ndarray, name: str) -> None:
    np.testing.assert_array_equal(P, P.T, err_msg=f"{name} is not symmetric")
    eig = np.linalg.eigvalsh(P)
    assert eig.min() >= -1e-12 * max(1.0, float(eig.max())), f"{name} has eigenvalue {eig.min():.3g}"


@PROPERTY
@given(samples=st.lists(st.tuples(DT, st.tuples(*PLAUSIBLE)), min_size=1, max_size=80))
def test_phase_ekf_covariance_stays_psd_and_phase_in_range(
    model: TrainedModel, samples: list[tuple[float, tuple[float, ...]]]
) -> None:
    ekf = PhaseEKF(model.coef, model.noise, 0.9)
    for dt, z in samples:
        ekf.predict(dt)
        assert 0.0 <= ekf.phase < 1.0
        ekf.update(np.array(z))
        assert 0.0 <= ekf.phase < 1.0, ekf.phase
        assert np.all(np.isfinite(ekf.x)) and np.all(np.isfinite(ekf.P))
        _assert_psd(ekf.P, "P")


@PROPERTY
@given(
    samples=st.lists(
        st.tuples(DT, st.lists(ANY, min_size=6, max_size=6), st.sampled_from([None, None, True, False])),
        min_size=1,
        max_size=80,
    ),
    raw_heel=st.booleans(),
)
def test_pipeline_state_stays_valid_and_no_nan_reaches_the_torque(
    model: TrainedModel, samples: list[tuple[float, list[float], bool | None]], raw_heel: bool
) -> None:
    pipe = GaitStatePipeline(model, PipelineConfig(max_torque=MAX_TORQUE, torque_gain=3.0))
    t = 0.0
    for dt, raw, hs in samples:
        t += dt
        e = pipe.step(t, np.array(raw), hs, heel_filtered=not raw_heel)
        assert 0.0 <= e.torque_Nm <= MAX_TORQUE  # NaN fails this too
        assert 0.0 <= e.phase < 1.0 and 0.0 <= e.tbe_phase < 1.0
        assert all(math.isfinite(v) for v in (e.phase_rate, e.stride_length_m, e.incline_deg))
        assert np.all(np.isfinite(pipe.ekf.x))
        _assert_psd(pipe.ekf.P, "EKF P")
        assert pipe.backup is not None
        assert 0.0 <= pipe.backup.phase < 1.0 and np.all(np.isfinite(pipe.backup.x))
        _assert_psd(pipe.backup.P, "backup P")


@pytest.mark.parametrize("phase", [0.0, 1e-18, 5e-324])
def test_a_phase_just_below_zero_wraps_to_zero_not_one(model: TrainedModel, phase: float) -> None:
    """``p - floor(p)`` of p = -1e-18 rounds to 1.0: predict with a slightly negative phase rate (the
    health check allows down to -0.5 /s) used to leave the phase at exactly 1.0."""
    ekf = PhaseEKF(model.coef, model.noise, 0.9)
    ekf.x[:] = [phase, -1e-16, 0.0, 0.0]
    ekf.predict(0.01)
    assert ekf.phase == 0.0
    ekf.x[:] = [0.3, -1.0, 0.0, 0.0]
    ekf.predict(0.01)
    assert ekf.phase == pytest.approx(0.29)

"""The bench's library baselines compute what gaitscope's estimators compute: the filterpy twin of the
standalone heel-strike backup sample for sample, the phase EKF core as the compiled filter."""

from __future__ import annotations

import numpy as np
import pytest

from gaitscope.estimators.heel_strike import HeelStrikeBackup
from gaitscope.estimators.phase_ekf import PhaseEKF
from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.estimators.protocol import HEEL_STRIKE, input_names
from gaitscope.sessions.formats.models import default_model_path, load_model
from gaitscope.sessions.offline.baselines import BASELINES, PhaseEKFCore, ReferenceHeelStrikeBackup
from gaitscope.sessions.offline.replay import measurements
from gaitscope.sessions.registry import ESTIMATORS, StackContext
from gaitscope.sessions.synth.trials import replay_input, sensor_trial

TOL = 1e-9


@pytest.fixture(scope="module")
def model() -> TrainedModel:
    return load_model(default_model_path())[0]


@pytest.fixture(scope="module")
def trial() -> tuple[np.ndarray, dict[str, np.ndarray], float]:
    """12 strides on level ground then up 5 deg: times, channels by name, leg length."""
    sensors, leg, _ = sensor_trial([(1.2, 0.0, 6), (1.0, 5.0, 6)], subject=1, rate_hz=100.0)
    channels = {str(c): sensors[c].to_numpy(np.float64) for c in sensors.columns}
    return sensors["time_s"].to_numpy(np.float64), channels, leg


def test_every_baseline_belongs_to_a_registered_estimator_and_tbe_and_detector_have_none() -> None:
    assert set(BASELINES) <= set(ESTIMATORS)
    assert set(BASELINES) == {"phase_ekf", "hs_backup"}
    assert BASELINES["hs_backup"].same_step and not BASELINES["phase_ekf"].same_step


@pytest.mark.parametrize("mask", [None, np.array([True, True, False, False, True, True])])
def test_filterpy_backup_matches_the_standalone_backup(model: TrainedModel, trial, mask) -> None:
    time_s, channels, leg = trial
    ours = HeelStrikeBackup.standalone(model.coef, model.noise, leg, channel_mask=mask)
    ref = ReferenceHeelStrikeBackup(model.coef, model.noise, leg, channel_mask=mask)
    z = np.column_stack([channels[c] for c in input_names(ours)])
    z[::7, 1:3] = np.nan  # foot IMU missing now and then
    z[::13, 1:5] = np.nan  # every angle missing: no update, prediction only
    t = time_s.copy()
    t[len(t) // 2 :] += 1.5  # a gap longer than MAX_GAP_S: both restart
    worst = 0.0
    for k in range(t.size):
        y, y_ref = ours.step(float(t[k]), z[k]), ref.step(float(t[k]), z[k])
        worst = max(worst, float(np.abs(y - y_ref).max()))
        assert np.abs(ours.x - ref.x).max() < TOL
        assert np.abs(ours.P - ref.P).max() < TOL
    assert worst < TOL
    assert channels[HEEL_STRIKE].sum() > 10  # the heel strikes did reset the open-loop phase


def test_phase_ekf_core_is_the_compiled_filter_step_by_step(model: TrainedModel) -> None:
    sensors, leg, mass = sensor_trial([(1.2, 0.0, 3)], rate_hz=100.0)
    data = replay_input(sensors)
    z = measurements(data)
    core = PhaseEKFCore(StackContext(model, leg, mass, 0.01))
    fast = PhaseEKF(model.coef, model.noise, leg)
    t = data.time_s
    for k in range(t.size):
        fast.predict(0.01 if k == 0 else float(t[k] - t[k - 1]))
        fast.update(z[k])
        x = core.step(float(t[k]), z[k])
        d = np.abs(x - fast.x)
        d[0] = min(d[0], 1 - d[0])
        assert d.max() < TOL and np.abs(core.P - fast.P).max() < TOL

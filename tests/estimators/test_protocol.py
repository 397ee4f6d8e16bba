"""Every estimator a stack can run implements :class:`gaitscope.estimators.protocol.Estimator`, and behind the
interface computes what it computed before (the pipeline's numbers, sample for sample)."""

from __future__ import annotations

import itertools
from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd
import pytest

from gaitscope.estimators.detector import HeelStrikeDetector
from gaitscope.estimators.heel_strike import HeelStrikeBackup
from gaitscope.estimators.lock import LockConfig
from gaitscope.estimators.phase_ekf_estimator import PhaseEKFEstimator
from gaitscope.estimators.pipeline import GaitStatePipeline, PipelineConfig, TrainedModel
from gaitscope.estimators.protocol import HEEL_STRIKE, SENSOR_CHANNELS, Estimator, elapsed, input_names, output_names
from gaitscope.estimators.tbe import TimingBasedEstimator
from gaitscope.sessions.offline.crossval import stride_rmse, wrapped
from gaitscope.sessions.schema import SensorFrame
from gaitscope.sessions.synth.trials import sensor_trial

LEG = 0.9
CHANNELS = (*SENSOR_CHANNELS, HEEL_STRIKE)
UNITS = {"1", "1/s", "m", "deg", "bool", "code"}


def _factories(model: TrainedModel) -> dict[str, Callable[[], Estimator]]:
    return {
        "phase_ekf": lambda: PhaseEKFEstimator(model, PipelineConfig(leg_length=LEG), 0.01),
        "tbe": TimingBasedEstimator,
        "hs_detector": HeelStrikeDetector,
        "hs_backup": lambda: HeelStrikeBackup.standalone(model.coef, model.noise, LEG, channel_mask=model.channel_mask),
    }


NAMES = ("phase_ekf", "tbe", "hs_detector", "hs_backup")


@pytest.fixture(scope="module")
def walk() -> tuple[pd.DataFrame, float]:
    sensors, leg, _ = sensor_trial([(1.2, 0.0, 10), (1.0, 5.0, 10)], subject=1, rate_hz=100.0)
    return sensors, leg


def _z(est: Estimator, row: dict[str, Any]) -> np.ndarray:
    return np.array([row.get(name, np.nan) for name in input_names(est)], dtype=np.float64)


def _run(est: Estimator, sensors: pd.DataFrame, heel_strikes: bool = True, n: int | None = None) -> np.ndarray:
    rows: list[dict[str, Any]] = [{str(k): v for k, v in r.items()} for r in sensors.to_dict("records")[:n]]
    out = []
    for row in rows:
        if not heel_strikes:
            row = {k: v for k, v in row.items() if k != HEEL_STRIKE}
        else:
            row = {**row, HEEL_STRIKE: float(row[HEEL_STRIKE])}
        out.append(est.step(float(row["time_s"]), _z(est, row)))
    return np.array(out)


@pytest.mark.parametrize("name", NAMES)
def test_every_estimator_satisfies_the_protocol(small_model: TrainedModel, name: str, walk) -> None:
    est = _factories(small_model)[name]()
    assert isinstance(est, Estimator)
    assert est.name == name
    assert set(input_names(est)) <= set(CHANNELS) and len(set(input_names(est))) == len(input_names(est))
    assert set(est.inputs).isdisjoint(est.optional_inputs)
    assert len(set(output_names(est))) == len(est.outputs) and {u for _, u in est.outputs} <= UNITS
    sensors, _ = walk
    y = _run(est, sensors, n=300)
    assert y.shape == (300, len(est.outputs)) and y.dtype == np.float64 and np.all(np.isfinite(y))
    first = est.step(3.5, _z(est, {}))  # every channel missing: still finite outputs
    assert np.all(np.isfinite(first))
    assert est.step(3.51, _z(est, {})) is not first  # a new array each sample
    for arr in (est.state, est.covariance):
        assert arr is None or (isinstance(arr, np.ndarray) and np.all(np.isfinite(arr)))
    with pytest.raises(ValueError, match="time must increase"):
        est.step(3.51, _z(est, {}))
    with pytest.raises(TypeError, match="no tuning parameter"):
        est.retune(no_such_parameter=1.0)
    # reset: the same outputs again from the same samples
    est.reset()
    again = _run(est, sensors, n=300)
    np.testing.assert_array_equal(again, y)


def test_channels_are_the_wire_names_of_a_sensor_frame() -> None:
    assert set(CHANNELS) <= set(SensorFrame.model_fields)


def test_retune_takes_the_declared_parameters(small_model: TrainedModel) -> None:
    ekf = PhaseEKFEstimator(small_model)
    ekf.retune(measurement_noise_scale=2.0)
    assert ekf.pipeline.ekf.config.measurement_noise_scale == 2.0
    tbe = TimingBasedEstimator()
    tbe.retune(initial_period=1.2)
    tbe.reset()
    assert tbe.state is not None and tbe.state[1] == pytest.approx(1 / 1.2)
    with pytest.raises(ValueError, match="periods"):
        tbe.retune(min_period=5.0)
    det = HeelStrikeDetector()
    det.retune(refractory_s=0.6)
    assert det.config.refractory_s == 0.6
    backup = HeelStrikeBackup.standalone(small_model.coef, small_model.noise, LEG)
    backup.retune(measurement_noise_scale=3.0)
    np.testing.assert_allclose(backup._rbar, small_model.noise.mean() * 3.0)


def test_phase_ekf_estimator_is_the_pipeline_sample_for_sample(small_model: TrainedModel, walk) -> None:
    """On walking without standing, the supervised estimator is the pipeline: throughout with its adaptation
    to cadence changes off (``rate_noise_scale`` 1), and by default until the supervisor first adapts (this walk
    changes speed, 1.2 to 1.0 m/s, after 10 strides; with the true heel strikes not before that)."""
    sensors, leg = walk
    config = PipelineConfig(leg_length=leg)
    rows = sensors.to_dict("records")
    change = float(sensors.loc[sensors[HEEL_STRIKE] > 0, "time_s"].iloc[10])  # the first stride at 1.0 m/s
    for given, lock in itertools.product((True, False), (LockConfig(rate_noise_scale=1.0), LockConfig())):
        est = PhaseEKFEstimator(small_model, config, 0.01, lock)  # heel strikes given, then detected
        pipe = GaitStatePipeline(small_model, config, 0.01)
        names = output_names(est)
        adapted, heel_strikes = None, 0.0
        for row in rows:
            y = est.step(float(row["time_s"]), _z(est, row if given else {**row, HEEL_STRIKE: np.nan}))
            raw = np.array([row[c] for c in SENSOR_CHANNELS])
            e = pipe.step(float(row["time_s"]), raw, bool(row[HEEL_STRIKE]) if given else None)
            got = dict(zip(names, y, strict=True))
            heel_strikes += got[HEEL_STRIKE]
            if adapted is not None and lock.rate_noise_scale != 1.0:
                continue
            assert got["phase"] == e.phase and got["incline_deg"] == e.incline_deg
            assert got["stride_length_m"] == e.stride_length_m and got["phase_rate"] == e.phase_rate
            assert got[HEEL_STRIKE] == e.heel_strike and got["backup_reset"] == e.backup_reset
            assert got["foot_pred_deg"] == pipe.predicted[0]
            if est.supervisor.adapt_left > 0 and adapted is None:
                adapted = float(row["time_s"])
        assert heel_strikes >= 15
        assert adapted is not None and (adapted > change or not given)  # the speed change is seen


def test_detector_and_tbe_are_the_pipelines_own(small_model: TrainedModel, walk) -> None:
    """Fed as a stack feeds them, the detector finds the pipeline's heel strikes and the TBE gives its
    ``tbe_phase``, across a gap that restarts them all."""
    sensors, leg = walk
    sensors = sensors.copy()
    sensors.loc[sensors.index >= 700, "time_s"] += 2.0  # a 2 s gap: everything restarts
    pipe = GaitStatePipeline(small_model, PipelineConfig(leg_length=leg), 0.01)
    det, tbe = HeelStrikeDetector(), TimingBasedEstimator()
    faults = []
    for row in sensors.to_dict("records"):
        t = float(row["time_s"])
        e = pipe.step(t, np.array([row[c] for c in SENSOR_CHANNELS]), None)
        hs = det.step(t, _z(det, row))
        phase = tbe.step(t, hs)
        assert bool(hs[0]) == e.heel_strike and phase[0] == e.tbe_phase
        faults.append(e.fault)
    assert faults.count("gap") == 1


def test_standalone_backup_tracks_phase_and_incline(small_model: TrainedModel, walk) -> None:
    sensors, leg = walk
    est = HeelStrikeBackup.standalone(small_model.coef, small_model.noise, leg, channel_mask=small_model.channel_mask)
    y = _run(est, sensors)
    hs = sensors[HEEL_STRIKE].to_numpy(bool)
    err = stride_rmse(wrapped(y[:, 0] - sensors["gt_phase"].to_numpy()), hs)
    assert np.mean(err[3:]) < 0.05
    last = sensors["time_s"].to_numpy() > sensors["time_s"].iloc[-1] - 3  # on the +5 deg ramp
    assert abs(np.mean(y[last, 3]) - 5.0) < 3.0
    assert est.resets == 0 and est.ekf is None  # nothing to reset on its own


def test_elapsed_restarts_after_a_gap() -> None:
    assert elapsed(None, 5.0) == (0.0, False)
    assert elapsed(1.0, 1.5) == (0.5, False)
    assert elapsed(1.0, 2.5) == (0.0, True)
    for bad in (1.0, 0.5, float("nan")):
        with pytest.raises(ValueError, match="time must increase"):
            elapsed(1.0, bad)

"""``GaitStatePipeline.run`` (the compiled whole-trial loop of ``gaitscope.estimators._batch``) against ``step``.

Every output and the pipeline's whole state must match sample-by-sample streaming, on cohort trials
and on adversarial input (NaN, infinities, huge and denormal values, gaps, forced divergence), for
every branch: given and detected heel strikes, raw and pre-filtered heel positions, no backup, the
no-task EKF, a model without heel outputs, retuned noise, gap restarts and divergence resets.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gaitscope.estimators import _batch, _kernels
from gaitscope.estimators.phase_ekf import EKFConfig
from gaitscope.estimators.pipeline import GaitStatePipeline, HealthLimits, PipelineConfig, TrainedModel
from gaitscope.sessions.formats.models import default_model_path, load_model
from gaitscope.sessions.offline.replay import measurements
from gaitscope.sessions.synth.trials import replay_input, sensor_trial

FLOATS = ("phase", "phase_rate", "stride_length_m", "incline_deg", "torque_Nm", "tbe_phase")
EXACT = ("heel_strike", "backup_reset", "fault", "implausible")
TOL = 1e-12
STALE = " (edited estimators/_kernels.py? delete estimators/__pycache__/_batch* and rerun)"


@pytest.fixture(scope="module")
def model() -> TrainedModel:
    return load_model(default_model_path())[0]


@pytest.fixture(scope="module")
def walk() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float, float]:
    """Two minutes of the cohort's subject 1 walking three conditions: times, measurements with
    the heel already high-passed, raw measurements, true heel strikes, leg length, mass."""
    sensors, leg, mass = sensor_trial([(1.2, 0.0, 40), (1.0, 7.5, 40), (0.8, -5.0, 40)], subject=1)
    data = replay_input(sensors)
    raw = np.column_stack([data.signals[k] for k in data.signals])
    return data.time_s, measurements(data), raw, np.asarray(data.heel_strike), leg, mass


def _stream(
    pipe: GaitStatePipeline, t: np.ndarray, z: np.ndarray, hs: np.ndarray | None, heel_filtered: bool = False
) -> dict[str, np.ndarray]:
    steps = [pipe.step(float(t[k]), z[k], None if hs is None else bool(hs[k]), heel_filtered) for k in range(t.size)]
    return {f: np.array([getattr(e, f) for e in steps]) for f in FLOATS + EXACT}


def _state(pipe: GaitStatePipeline) -> dict[str, Any]:
    """Everything a later step depends on, by name."""
    ekf, bk, tbe, det = pipe.ekf, pipe.backup, pipe.tbe, pipe.detector
    state: dict[str, Any] = {
        "t": pipe._t,
        "implausible": pipe.implausible,
        "restarts": pipe.restarts,
        "resets": pipe.resets,
        "highpass": pipe.highpass._zi,
        "detector_last": det._last_hs,
        "detector_vel": det._prev_vel,
        "detector_acc": len(det._acc),
    }
    for name in ("x", "P", "y", "S", "K", "z_pred", "H", "R", "log_likelihood", "mahalanobis"):
        state[f"ekf.{name}"] = getattr(ekf, name)
    for name in ("x", "period", "t", "_last_hs", "_seen_hs", "min_period", "max_period"):
        state[f"tbe.{name}"] = getattr(tbe, name)
    if bk is not None:
        for name in ("x", "P", "phase", "phase_rate", "sse_ekf", "sse_hp", "resets", "_last_hs"):
            state[f"backup.{name}"] = getattr(bk, name)
    return state


def _assert_same(batch: dict[str, np.ndarray], stream: dict[str, np.ndarray]) -> None:
    for key in FLOATS:
        diff = np.abs(batch[key] - stream[key])
        both_nan = np.isnan(batch[key]) & np.isnan(stream[key])
        worst = float(np.max(np.where(both_nan, 0.0, diff), initial=0.0))
        assert worst <= TOL, f"{key}: batch and streaming differ by {worst:.3g}{STALE}"
    for key in EXACT:
        np.testing.assert_array_equal(batch[key], stream[key], err_msg=key + STALE)


def _assert_same_state(p: GaitStatePipeline, q: GaitStatePipeline) -> None:
    a, b = _state(p), _state(q)
    assert a.keys() == b.keys()
    for key, u in a.items():
        v = b[key]
        if u is None or v is None:
            assert u is v, key
        else:
            np.testing.assert_allclose(
                np.asarray(u, float), np.asarray(v, float), rtol=0, atol=TOL, equal_nan=True, err_msg=key + STALE
            )


def _both(
    model: TrainedModel,
    config: PipelineConfig,
    t: np.ndarray,
    z: np.ndarray,
    hs: np.ndarray | None,
    heel_filtered: bool = False,
    prepare: Any = None,
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], GaitStatePipeline]:
    """Batch and streaming runs of two fresh pipelines (``prepare`` applied to each first), compared;
    returns both outputs and the batch pipeline."""
    p, q = GaitStatePipeline(model, config), GaitStatePipeline(model, config)
    if prepare is not None:
        prepare(p)
        prepare(q)
    batch, stream = p.run(t, z, hs, heel_filtered), _stream(q, t, z, hs, heel_filtered)
    _assert_same(batch, stream)
    _assert_same_state(p, q)
    return batch, stream, p


# --- the cohort ----------------------------------------------------------------------------------


def test_cohort_trial_with_given_heel_strikes_is_identical(model: TrainedModel, walk) -> None:
    t, z, _, hs, leg, mass = walk
    batch, stream, _ = _both(model, PipelineConfig(leg_length=leg, body_mass_kg=mass), t, z, hs, heel_filtered=True)
    assert batch["heel_strike"].sum() == hs.sum() > 100
    assert np.all(batch["fault"] == "") and batch["torque_Nm"].max() > 5.0
    for key in FLOATS:  # in practice bit for bit: the same compiled kernels, the same operations
        np.testing.assert_array_equal(batch[key], stream[key])


def test_detected_heel_strikes_and_raw_heel_positions(model: TrainedModel, walk) -> None:
    t, _, raw, _, leg, mass = walk
    batch, _, _ = _both(model, PipelineConfig(leg_length=leg, body_mass_kg=mass), t, raw, None)
    assert batch["heel_strike"].sum() > 100


@pytest.mark.parametrize(
    "change",
    [
        {"use_backup": False},
        {"ekf": EKFConfig(no_task=True)},
        {"ekf": EKFConfig(measurement_noise_scale=2.5, process_noise_scale=0.3), "torque_gain": 2.0},
        {"health": HealthLimits(max_phase_rate=1.0, max_abs_incline=2.0)},  # resets every few samples
        {"max_gap_s": 0.015},  # every jittered sample a restart
    ],
    ids=["no-backup", "no-task", "tuned", "tight-health", "tiny-gap"],
)
def test_every_configuration_is_identical(model: TrainedModel, walk, change: dict[str, Any]) -> None:
    t, z, _, hs, leg, mass = walk
    part = slice(4000, 7000)  # level walking, then up the 7.5 deg ramp
    n = part.stop - part.start
    jitter = t[part] + np.random.default_rng(3).uniform(0, 0.006, n) * (np.arange(n) % 7 == 0)
    config = replace(PipelineConfig(leg_length=leg, body_mass_kg=mass), **change)
    batch, _, pipe = _both(model, config, jitter, z[part], hs[part], heel_filtered=True)
    if "health" in change:
        assert pipe.resets > 20 and (batch["fault"] == "diverged").sum() == pipe.resets
    if "max_gap_s" in change:
        assert pipe.restarts > 20 and 0 < (batch["fault"] == "gap").sum() <= pipe.restarts


def test_a_model_without_heel_outputs(model: TrainedModel, walk) -> None:
    t, z, _, hs, leg, mass = walk
    no_heel = replace(model, outputs=(True, True, False, False))
    _both(no_heel, PipelineConfig(leg_length=leg, body_mass_kg=mass), t[:2000], z[:2000], hs[:2000], True)


def test_retune_between_runs_is_followed(model: TrainedModel, walk) -> None:
    t, z, _, hs, leg, mass = walk

    def retune(pipe: GaitStatePipeline) -> None:
        pipe.retune(torque_gain=2.5, max_torque=12.0, measurement_noise_scale=0.5, process_noise_scale=4.0)

    config = PipelineConfig(leg_length=leg, body_mass_kg=mass)
    batch, _, _ = _both(model, config, t[:2000], z[:2000], hs[:2000], True, retune)
    assert batch["torque_Nm"].max() == 12.0


# --- adversarial input ---------------------------------------------------------------------------


def _adversarial(seed: int, n: int = 4000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times with jitter, tiny steps and gaps; values plausible, NaN, infinite, huge or denormal."""
    rng = np.random.default_rng(seed)
    dt = rng.choice([0.01, 1e-9, 0.004, 1.5, 30.0], size=n, p=[0.9, 0.02, 0.05, 0.02, 0.01])
    t = np.cumsum(dt) + rng.uniform(-1e6, 1e6)
    z = rng.normal(0.0, 1.0, (n, 6)) * np.array([20.0, 200.0, 20.0, 200.0, 0.2, 0.1])
    weird = rng.choice([np.nan, np.inf, -np.inf, 1e308, -1e308, 5e-324, 179.99, -3999.0], size=(n, 6))
    pick = rng.random((n, 6)) < 0.08
    z[pick] = weird[pick]
    return t, z, rng.random(n) < 0.02


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("detect", [False, True])
def test_adversarial_input_is_identical(model: TrainedModel, seed: int, detect: bool) -> None:
    t, z, hs = _adversarial(seed)
    batch, _, pipe = _both(model, PipelineConfig(max_torque=25.0, torque_gain=3.0), t, z, None if detect else hs)
    assert pipe.restarts > 10 and pipe.implausible > 100 and batch["backup_reset"].any()
    assert np.all(np.isfinite(batch["torque_Nm"])) and batch["torque_Nm"].max() <= 25.0


def test_diverged_filter_and_poisoned_backup_are_reset_alike(model: TrainedModel) -> None:
    t, z, hs = _adversarial(5, 600)

    def poison(pipe: GaitStatePipeline) -> None:
        pipe.step(t[0] - 1.0, np.full(6, np.nan))
        pipe.ekf.x[1] = math.nan  # as if a numerical fault had happened inside the filter
        assert pipe.backup is not None
        pipe.backup.x[0] = math.inf

    batch, _, pipe = _both(model, PipelineConfig(), t, z, hs, prepare=poison)
    assert batch["fault"][0] == "diverged" and pipe.resets >= 1


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    samples=st.lists(
        st.tuples(
            st.one_of(st.floats(1e-9, 3.0), st.just(0.01)),
            st.lists(st.one_of(st.floats(), st.floats(-200, 200)), min_size=6, max_size=6),
            st.sampled_from([True, False, False, False]),
        ),
        min_size=1,
        max_size=60,
    ),
    detect=st.booleans(),
    raw_heel=st.booleans(),
)
def test_any_sequence_is_identical(
    model: TrainedModel, samples: list[tuple[float, list[float], bool]], detect: bool, raw_heel: bool
) -> None:
    t = np.cumsum([dt for dt, _, _ in samples])
    t = t[np.concatenate(([True], np.diff(t) > 0))]  # a step below float resolution is no step
    n = t.size
    z = np.array([v for _, v, _ in samples])[:n]
    hs = None if detect else np.array([h for _, _, h in samples])[:n]
    _both(model, PipelineConfig(max_torque=30.0), t, z, hs, heel_filtered=not raw_heel)


# --- mixing run and step, errors -----------------------------------------------------------------


def test_run_and_step_may_be_mixed(model: TrainedModel, walk) -> None:
    t, _, raw, hs, leg, mass = walk
    config = PipelineConfig(leg_length=leg, body_mass_kg=mass)
    t, raw, hs = t[:3000], raw[:3000], hs[:3000]
    streamed = _stream(q := GaitStatePipeline(model, config), t, raw, hs)
    p = GaitStatePipeline(model, config)
    first = p.run(t[:1000], raw[:1000], hs[:1000])
    middle = _stream(p, t[1000:1700], raw[1000:1700], hs[1000:1700])
    last = p.run(t[1700:], raw[1700:], hs[1700:])
    _assert_same({k: np.concatenate([first[k], middle[k], last[k]]) for k in streamed}, streamed)
    _assert_same_state(p, q)


def test_bad_times_raise_as_step_does_and_change_nothing(model: TrainedModel) -> None:
    pipe = GaitStatePipeline(model)
    pipe.step(1.0, np.zeros(6))
    before = _state(pipe)
    for t, message in [
        ([1.5, 1.5], "time must increase: 1.5 after 1.5"),
        ([0.5, 2.0], "time must increase: 0.5 after 1.0"),
        ([2.0, math.nan], "time must be finite, got nan"),
    ]:
        with pytest.raises(ValueError, match=f"^{message}$"):
            pipe.run(np.array(t), np.zeros((2, 6)))
    with pytest.raises(ValueError, match=r"z must have shape \(2, 6\)"):
        pipe.run(np.array([2.0, 3.0]), np.zeros((2, 5)))
    after = _state(pipe)
    assert after["t"] == 1.0
    for key, value in before.items():
        np.testing.assert_array_equal(after[key], value, err_msg=key)


def test_an_empty_batch_changes_nothing(model: TrainedModel) -> None:
    pipe = GaitStatePipeline(model)
    out = pipe.run(np.empty(0), np.empty((0, 6)))
    assert all(v.shape == (0,) for v in out.values()) and pipe._t is None


def test_the_compiled_cache_follows_the_kernels_file() -> None:
    """numba keys a cache on its function's own file; this module's also on ``_kernels.py``."""
    locator = _batch._run._cache._impl.locator
    assert isinstance(locator, _batch._KernelsStampedLocator)
    kernels = hashlib.sha256(Path(_kernels.__file__).read_bytes()).digest()
    assert locator.get_source_stamp()[1] == kernels

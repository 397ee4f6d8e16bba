"""The estimation state a recording keeps (:mod:`gaitscope.sessions.formats.stack_state`): restored, it steps on
exactly as the estimator it was taken of; its JSON is the schema's; a damaged or hostile one is refused before
anything it names is called (the restricted unpickler), with a reason."""

from __future__ import annotations

import functools
import json
import pickle
from pathlib import Path

import numpy as np
import pytest

from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.sessions.estimation import FrameEstimator
from gaitscope.sessions.formats import stack_state
from gaitscope.sessions.formats.models import default_model_path, load_model
from gaitscope.sessions.live.sources import frames_from_table
from gaitscope.sessions.schema import EstimationState, SensorFrame, SessionSettings
from gaitscope.sessions.synth.trials import sensor_trial


@functools.cache
def _model() -> TrainedModel:
    return load_model(default_model_path())[0]


@pytest.fixture
def model() -> TrainedModel:
    return _model()


@pytest.fixture(scope="module")
def frames() -> list[SensorFrame]:
    sensors, _, _ = sensor_trial([(1.2, 3.0, 8)], rate_hz=100.0)
    return list(frames_from_table(sensors))


def _state(estimator: FrameEstimator, data: bytes | None = None) -> dict[str, object]:
    data = stack_state.capture(estimator, _model()) if data is None else data
    return json.loads(stack_state.encoded(estimator.last_t, estimator.stack.names, data))  # type: ignore[no-any-return]


def test_a_restored_estimator_steps_on_bit_identically(model: TrainedModel, frames: list[SensorFrame]) -> None:
    live = FrameEstimator(model, 0.9, 70.0, SessionSettings(), 0.01)
    for f in frames[:300]:
        live.step(f, 0)
    live.retune(SessionSettings(primary="tbe", torque_gain=0.7))  # a switch still blending, a gain ramp running
    for f in frames[300:340]:
        live.step(f, 0)
    recorded = _state(live)
    again = stack_state.restore(recorded, model, live.stack.names)
    again.replaying(0.0)
    assert again is not live and again.stack.names == live.stack.names
    for f in frames[340:]:
        a, b = live.step(f, 0), again.step(f, 0)
        assert a == b
        assert all(
            (x is None and y is None) or (x is not None and y is not None and np.array_equal(x, y))
            for x, y in zip(live.last.outputs, again.last.outputs, strict=True)  # type: ignore[union-attr]
        )


def test_the_json_is_the_schemas_and_the_model_is_not_in_it(model: TrainedModel) -> None:
    est = FrameEstimator(model, 0.9, 70.0, SessionSettings(), 0.01)
    data = stack_state.capture(est, model)
    text = stack_state.encoded(1.5, est.stack.names, data)
    assert EstimationState.model_validate_json(text) == stack_state.message(1.5, est.stack.names, data)
    assert len(data) < len(pickle.dumps(est, protocol=5)) - 40_000  # the gait model is a reference


def test_another_stack_or_a_damaged_state_is_refused(model: TrainedModel) -> None:
    est = FrameEstimator(model, 0.9, 70.0, SessionSettings(), 0.01)
    good = _state(est)
    cases = {
        "another estimator stack": (good, ("phase_ekf", "tbe")),
        "checksum does not match": ({**good, "sha256": "0" * 64}, est.stack.names),
        "not base64": ({**good, "data": "@@@@"}, est.stack.names),
        "encoded as": ({**good, "encoding": "other"}, est.stack.names),
        "not valid": ({**good, "t": "soon"}, est.stack.names),
        "cannot be read": (_state(est, stack_state.capture(est, model)[:-100]), est.stack.names),
    }
    for why, (recorded, names) in cases.items():
        with pytest.raises(stack_state.StateRefused, match=why):
            stack_state.restore(recorded, model, names)


def _pickle_naming(module: str, name: str) -> bytes:
    """A protocol-0 pickle that calls ``module.name("x")``."""
    return f"c{module}\n{name}\n(S'x'\ntR.".encode()


@pytest.mark.parametrize(
    ("module", "name"),
    [
        ("os", "system"),  # anything outside gaitscope
        ("builtins", "eval"),
        ("gaitscope.sessions.formats.recording", "Recorder"),  # a gaitscope class that writes files
        ("gaitscope.sessions.files", "Path"),
        ("gaitscope.sessions.schema", "BaseModel"),  # a class imported into an allowed module
        ("gaitscope.estimators.pipeline", "replace"),  # a function, not a class
        ("gaitscope.sessions.stack", "EstimatorStack.set_primary"),  # a dotted name
    ],
)
def test_a_hostile_state_is_refused_before_anything_is_called(
    model: TrainedModel, tmp_path: Path, module: str, name: str
) -> None:
    est = FrameEstimator(model, 0.9, 70.0, SessionSettings(), 0.01)
    with pytest.raises(stack_state.StateRefused, match=f"names {module}.{name}, which is not allowed"):
        stack_state.restore(_state(est, _pickle_naming(module, name)), model, est.stack.names)


class _Crafted:
    """Pickles as a call of ``stack_state._View`` with the arguments given (what a hostile file could hold)."""

    def __init__(self, *args: object):
        self.args = args

    def __reduce__(self) -> tuple[object, tuple[object, ...]]:
        return stack_state._View, self.args


def test_a_bad_view_or_reference_is_refused(model: TrainedModel) -> None:
    est = FrameEstimator(model, 0.9, 70.0, SessionSettings(), 0.01)
    base = np.zeros(4)
    for args in (
        (base, 16, (4,), (8,), np.dtype("f8")),  # past the end of its base
        (base, 0, (1,), (8,), np.dtype(object)),  # objects: their bytes would be taken for pointers
        (np.zeros(2, dtype=object), 0, (1,), (8,), np.dtype("f8")),
        (base, -8, (1,), (8,), np.dtype("f8")),
        ("base", 0, (1,), (8,), np.dtype("f8")),
    ):
        with pytest.raises(stack_state.StateRefused, match="bad array view"):
            stack_state.restore(_state(est, pickle.dumps(_Crafted(*args), protocol=5)), model, est.stack.names)
    ok = pickle.dumps(_Crafted(base, 8, (2,), (8,), np.dtype("f8")), protocol=5)
    with pytest.raises(stack_state.StateRefused, match="not the estimator stack"):  # a view, but not an estimator
        stack_state.restore(_state(est, ok), model, est.stack.names)
    with pytest.raises(stack_state.StateRefused, match="refers to 'other'"):
        stack_state.restore(_state(est, b"\x80\x05\x8c\x05other\x94Q."), model, est.stack.names)

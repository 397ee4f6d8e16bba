"""The estimation state at a trial's start, recorded so that a review re-run resumes exactly where it was.

A trial of a live session usually begins with the estimators already running: their filters, the stack's
primary and blend, the torque gain's ramps, the IMU front ends, the GP-EKF's learned models, the personalized
filter's fingerprint, the frame estimator's clock and last frame. :func:`capture` takes all of it, the whole
:class:`~gaitscope.sessions.estimation.FrameEstimator`, as one pickle; the recording holds it as one
:class:`~gaitscope.sessions.schema.EstimationState` message on :data:`TOPIC` (JSON, the pickle in base64, so
Foxglove opens the file and lists it like any other message). :func:`restore` gives the estimator back, and a
re-run stepping the trial's frames through it reproduces what ran bit for bit
(:mod:`gaitscope.sessions.review.rerun`).

The gait model (:class:`~gaitscope.estimators.pipeline.TrainedModel`) is not stored: it and its arrays are
references that :func:`restore` resolves in the model the recorded settings name, as a re-run builds one.

A recording is a file a user can upload, so the pickle is loaded as hostile data ("Restricting Globals" in the
:mod:`pickle` documentation): :class:`_Unpickler` resolves only classes defined in the modules of
:data:`_MODULES` (the estimators and the session's estimation state: pure computation, no I/O), the few numpy
and builtin reconstructors an array and a container need (:data:`_OTHERS`), and the one model reference;
anything else (a function, a class imported into those modules from elsewhere, a dotted name) is refused with
:class:`StateRefused` before it is called. The SHA-256 of the pickle detects a damaged message.
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import io
import json
import pickle
import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Final

import numpy as np

from gaitscope.estimators.pipeline import TrainedModel
from gaitscope.sessions import schema

if TYPE_CHECKING:
    from gaitscope.sessions.estimation import FrameEstimator

__all__ = ["ENCODING", "TOPIC", "StateRefused", "capture", "encoded", "message", "restore"]

#: The recording's topic of the state (one message per trial, at the session time of its start).
TOPIC: Final = "/estimation_state"
#: How :attr:`~gaitscope.sessions.schema.EstimationState.data` is encoded: this module's pickle, in base64.
ENCODING: Final = "gaitscope-pickle-5"
_MODEL: Final = "model"
#: Modules whose own classes a state may hold: the estimators (pure numpy) and the session's estimation state.
_MODULES: Final = ("gaitscope.estimators.",)
_SESSION_MODULES: Final = frozenset(
    {
        "gaitscope.sessions.estimation",
        "gaitscope.sessions.stack",
        "gaitscope.sessions.torque_gain",
        "gaitscope.sessions.intent_boost",
        "gaitscope.sessions.schema",
    }
)
#: What else a state may name: numpy's array, scalar and dtype reconstructors (under both of numpy's module
#: names) and the builtin containers pickle names by reference.
_OTHERS: Final = frozenset(
    {
        ("numpy", "dtype"),
        ("numpy", "ndarray"),
        *((m, n) for m in ("numpy.core.multiarray", "numpy._core.multiarray") for n in ("scalar", "_reconstruct")),
        *((m, "_frombuffer") for m in ("numpy.core.numeric", "numpy._core.numeric")),
        ("builtins", "set"),
        ("builtins", "frozenset"),
        ("builtins", "complex"),
        ("collections", "deque"),
        ("collections", "OrderedDict"),
    }
)


class StateRefused(ValueError):
    """A recorded estimation state that cannot be restored (damaged, refused, or of another stack)."""


class _View:
    """An array that is a view of another, pickled as one (:class:`_Pickler`): pickle copies a view, which then
    no longer sees its base change (the phase EKF's pipeline high-passes the heel positions through a view of
    its measurement vector). ``np.ndarray(buffer=...)`` refuses an extent outside the base; arrays of objects
    are refused (their bytes are pointers)."""

    def __new__(  # type: ignore[misc]  # a reconstructor: makes an array, not an instance
        cls, base: object, offset: object, shape: object, strides: object, dtype: object
    ) -> np.ndarray[Any, Any]:
        if not (
            isinstance(base, np.ndarray)
            and base.flags.c_contiguous
            and not base.dtype.hasobject
            and isinstance(dtype, np.dtype)
            and not dtype.hasobject
            and isinstance(offset, int)
            and offset >= 0
            and isinstance(shape, tuple)
            and isinstance(strides, tuple)
            and all(isinstance(x, int) for x in (*shape, *strides))
        ):
            raise StateRefused("the recorded estimation state holds a bad array view")
        try:
            return np.ndarray(shape, dtype, buffer=base, offset=offset, strides=strides)
        except (TypeError, ValueError) as exc:
            raise StateRefused(f"the recorded estimation state holds a bad array view ({exc})") from None


class _Pickler(pickle.Pickler):
    """Pickles an estimator with its gait model and the model's parts (:func:`_model_parts`) as references, and
    arrays that are views of another as views of it (:class:`_View`)."""

    def __init__(self, file: io.BytesIO, model: TrainedModel):
        super().__init__(file, protocol=5)
        self.parts = {id(obj): path for path, obj in _model_parts(model).items()}

    def persistent_id(self, obj: Any) -> str | None:
        return self.parts.get(id(obj))

    def reducer_override(self, obj: Any) -> Any:
        if type(obj) is np.ndarray:
            base = obj.base
            if type(base) is np.ndarray and base.flags.c_contiguous and not base.dtype.hasobject:
                offset = obj.__array_interface__["data"][0] - base.__array_interface__["data"][0]
                return _View, (base, offset, obj.shape, obj.strides, obj.dtype)
        return NotImplemented


class _Unpickler(pickle.Unpickler):
    """Loads what :class:`_Pickler` wrote, refusing every global but those allowed (see the module docstring)."""

    def __init__(self, file: io.BytesIO, model: TrainedModel):
        super().__init__(file)
        self.parts = _model_parts(model)

    def find_class(self, module: str, name: str) -> Any:
        if (module, name) in _OTHERS:
            return super().find_class(module, name)
        if (module, name) == (__name__, "_View"):
            return _View
        if (module.startswith(_MODULES) or module in _SESSION_MODULES) and name.isidentifier():
            loaded = sys.modules.get(module)
            obj = getattr(loaded, name, None) if loaded is not None else None
            if isinstance(obj, type) and obj.__module__ == module and obj.__qualname__ == name:
                return obj
        raise StateRefused(f"the recorded estimation state names {module}.{name}, which is not allowed")

    def persistent_load(self, pid: Any) -> Any:
        if isinstance(pid, str) and pid in self.parts:
            return self.parts[pid]
        raise StateRefused(f"the recorded estimation state refers to {str(pid)[:40]!r}, which is not allowed")


def capture(estimator: FrameEstimator, model: TrainedModel) -> bytes:
    """The whole state of ``estimator`` between two samples, as a pickle without its gait model ``model``."""
    buf = io.BytesIO()
    _Pickler(buf, model).dump(estimator)
    return buf.getvalue()


def _model_parts(model: TrainedModel) -> dict[str, object]:
    """The gait model and the data it is made of (its fields, their arrays and fields), by a path that names
    them (``model``, ``model.noise``, ``model.noise.residual_cov``): what a state refers to rather than holds.
    Data only (arrays, dataclasses): nothing a pickle could call."""
    parts: dict[str, object] = {_MODEL: model}
    for name, value in vars(model).items():
        if isinstance(value, np.ndarray) or (hasattr(value, "__dict__") and not callable(value)):
            parts[f"{_MODEL}.{name}"] = value
            if not isinstance(value, np.ndarray):
                for inner, x in vars(value).items():
                    if isinstance(x, np.ndarray):
                        parts[f"{_MODEL}.{name}.{inner}"] = x
    return parts


def message(t: float, estimators: Sequence[str], data: bytes) -> schema.EstimationState:
    """The recording's message of a state ``data`` that :func:`capture` took at session time ``t`` of an
    estimator running ``estimators``."""
    return schema.EstimationState.model_validate_json(encoded(t, estimators, data))


def encoded(t: float, estimators: Sequence[str], data: bytes) -> bytes:
    """:func:`message` as the JSON the recording holds, built as text (the base64 of the state is most of
    the work; safe on a worker thread)."""
    head = {
        "t": float(t),
        "encoding": ENCODING,
        "estimators": list(estimators),
        "sha256": hashlib.sha256(data).hexdigest(),
    }
    return json.dumps(head).encode()[:-1] + b', "data": "' + base64.b64encode(data) + b'"}'


def restore(recorded: object, model: TrainedModel, estimators: tuple[str, ...]) -> FrameEstimator:
    """The estimator a recorded state (a ``/estimation_state`` message as read) holds, its gait model ``model``.

    Raises:
        StateRefused: a damaged or refused message, or one of a stack other than ``estimators``.
    """
    from gaitscope.sessions.estimation import FrameEstimator

    try:
        state = schema.EstimationState.model_validate(recorded)
    except ValueError as exc:
        raise StateRefused(f"the recorded estimation state is not valid ({_first_line(exc)})") from None
    if state.encoding != ENCODING:
        raise StateRefused(f"the recorded estimation state is encoded as {state.encoding!r}, not {ENCODING!r}")
    if tuple(state.estimators) != estimators:
        raise StateRefused("the recorded estimation state is of another estimator stack")
    try:
        data = base64.b64decode(state.data, validate=True)
    except (binascii.Error, ValueError):
        raise StateRefused("the recorded estimation state is damaged (not base64)") from None
    if hashlib.sha256(data).hexdigest() != state.sha256:
        raise StateRefused("the recorded estimation state is damaged (its checksum does not match)")
    try:
        estimator = _Unpickler(io.BytesIO(data), model).load()
    except StateRefused:
        raise
    except Exception as exc:  # a damaged pickle raises about anything
        raise StateRefused(f"the recorded estimation state cannot be read ({type(exc).__name__})") from None
    if not isinstance(estimator, FrameEstimator) or estimator.stack.names != estimators:
        raise StateRefused("the recorded estimation state is not the estimator stack the trial ran")
    return estimator


def _first_line(exc: Exception) -> str:
    return str(exc).splitlines()[0][:200]

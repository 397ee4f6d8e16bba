"""The one interface every estimator implements, so that a session can run a stack of them.

An estimator is a streaming object that turns named input channels into named outputs, one sample at
a time. It declares what it reads and what it writes, so that the session level (``gaitscope.sessions.stack``)
can check a source against it before the session starts, feed it, record its outputs on their own
channel and plot them, without knowing the algorithm:

- ``name``: the estimator's name in a stack (``phase_ekf``, ``tbe``, ...).
- ``inputs``: channels it needs (a source without one of them cannot run it); ``optional_inputs``:
  channels it uses when present. Channel names are those of the channel table
  (:mod:`gaitscope.estimators.channels`, the fields of ``gaitscope.sessions.schema.SensorFrame``:
  ``foot_angle_deg``, ..., ``heel_strike``); an estimator finds each in ``z`` by name
  (:func:`~gaitscope.estimators.channels.positions` of its :func:`input_names`).
- ``outputs``: ``(name, unit)`` pairs; ``step`` returns them in this order.
- ``tunables``: the parameter names ``retune`` accepts (an empty tuple: nothing to tune).
- ``step(t, z)``: one sample at time ``t`` (s, strictly increasing); ``z`` holds ``inputs`` then
  ``optional_inputs`` in declared order, NaN where a channel is missing for this sample (``heel_strike``
  is 1.0 or 0.0, NaN when unknown). Returns a new ``(len(outputs),)`` float array, every entry finite
  (booleans as 1.0 / 0.0): a non-finite output means the estimator failed.
- ``reset()``: back to the initial state, keeping the tuning.
- ``retune(**params)``: change tuning from the next ``step`` on; an unknown name raises ``TypeError``,
  a bad value ``ValueError``.
- ``state`` and ``covariance``: the filter's state vector and its covariance for inspection and health
  checks (None where meaningless, e.g. a detector has no covariance). Read-only views: do not modify.

The filters keep their filterpy-like ``predict`` / ``update`` / ``x`` / ``P`` interface underneath
(``docs/estimators.md``); this protocol is the streaming shape around it. Pure: no I/O, no clocks.
"""

from __future__ import annotations

from typing import Final, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "ANGLE_CHANNELS",
    "FAULTS",
    "HEEL_STRIKE",
    "MAX_GAP_S",
    "SENSOR_CHANNELS",
    "Estimator",
    "Output",
    "check_params",
    "elapsed",
    "input_names",
    "output_names",
]

#: ``(name, unit)`` of one output. Units: ``1`` (dimensionless, e.g. phase in cycles), ``1/s``, ``m``,
#: ``deg``, ``bool`` (1.0 / 0.0) and ``code`` (a small integer documented by the estimator).
Output = tuple[str, str]

#: The measurement channels, in the phase EKF's order, by their names in the channel table.
SENSOR_CHANNELS: Final = (
    "foot_angle_deg",
    "foot_vel_dps",
    "shank_angle_deg",
    "shank_vel_dps",
    "heel_forward_m",
    "heel_up_m",
)
#: The ipsilateral segment angles and their angular velocities, in the channel table (a source that sends an
#: angle can always give its velocity by differentiation).
ANGLE_CHANNELS: Final = {
    "foot_angle_deg": "foot_vel_dps",
    "shank_angle_deg": "shank_vel_dps",
    "thigh_angle_deg": "thigh_vel_dps",
}
#: The heel-strike channel: 1.0 on the sample of a heel strike, 0.0 otherwise, NaN when unknown.
HEEL_STRIKE: Final = "heel_strike"
#: Codes of an estimator's optional ``fault`` output (unit ``code``), by index: 0 nothing, 1 restarted
#: after a gap, 2 reset after its state diverged (the torque of such a sample is 0 when it drives it),
#: 3 its own torque was forced to 0 (the pipeline's; a stack computes its torque itself), 4 it lost
#: track and was reset from a backup (torque 0 on that sample, as 2), 5 it restarted as walking resumed
#: after standing still (:mod:`gaitscope.estimators.lock`).
FAULTS: Final = ("", "gap", "diverged", "torque", "lost", "resumed")
#: A longer gap between two samples (s) restarts a streaming estimator, as it restarts the pipeline
#: (``PipelineConfig.max_gap_s``): the walker may have stopped.
MAX_GAP_S: Final = 1.0


@runtime_checkable
class Estimator(Protocol):
    """What every estimator of a stack implements (see the module docstring)."""

    @property
    def name(self) -> str: ...

    @property
    def inputs(self) -> tuple[str, ...]: ...

    @property
    def optional_inputs(self) -> tuple[str, ...]: ...

    @property
    def outputs(self) -> tuple[Output, ...]: ...

    @property
    def tunables(self) -> tuple[str, ...]: ...

    @property
    def state(self) -> NDArray[np.float64] | None: ...

    @property
    def covariance(self) -> NDArray[np.float64] | None: ...

    def reset(self) -> None: ...

    def step(self, t: float, z: NDArray[np.float64]) -> NDArray[np.float64]: ...

    def retune(self, **params: float) -> None: ...


def input_names(estimator: Estimator) -> tuple[str, ...]:
    """The order of ``z`` in :meth:`Estimator.step`: required inputs, then optional ones."""
    return (*estimator.inputs, *estimator.optional_inputs)


def output_names(estimator: Estimator) -> tuple[str, ...]:
    """The names of the outputs, in the order :meth:`Estimator.step` returns them."""
    return tuple(name for name, _ in estimator.outputs)


def check_params(estimator: Estimator, params: dict[str, float]) -> None:
    """Raise ``TypeError`` for a parameter ``retune`` does not know (a helper for implementations)."""
    unknown = sorted(set(params) - set(estimator.tunables))
    if unknown:
        raise TypeError(f"{estimator.name} has no tuning parameter {', '.join(unknown)}; it has {estimator.tunables}")


def elapsed(last: float | None, t: float, max_gap_s: float = MAX_GAP_S) -> tuple[float, bool]:
    """``(dt, restart)`` for a sample at ``t`` after one at ``last`` (None: the first sample).

    ``dt`` is 0 on the first sample and after a gap longer than ``max_gap_s``, which also asks the
    estimator to restart from its initial state (``restart`` True), as the pipeline does.

    Raises:
        ValueError: ``t`` does not follow ``last`` (or is not a number).
    """
    if last is None:
        return 0.0, False
    dt = t - last
    if not dt > 0:
        raise ValueError(f"time must increase: {t} after {last}")
    return (0.0, True) if dt > max_gap_s else (dt, False)

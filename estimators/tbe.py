"""Timing-based phase estimate: the paper's TBE baseline (seed 000 section III-B)."""

from __future__ import annotations

from typing import Final

import numpy as np
from numpy.typing import NDArray

from gaitscope.estimators.basis import Array
from gaitscope.estimators.descriptor import Descriptor, Tunable, out
from gaitscope.estimators.protocol import HEEL_STRIKE, MAX_GAP_S, Output, check_params, elapsed

__all__ = ["DESCRIPTOR", "TimingBasedEstimator"]

_HS = np.ones(1)


class TimingBasedEstimator:
    """Timing-based phase estimate, the paper's TBE baseline (seed 000 III-B).

    ``phase = (t - t_lastHS) / T_prev mod 1`` with ``T_prev`` the duration of the previous stride only,
    initialised to ``initial_period`` (1 s in the paper). Same interface as the Kalman filters:
    :meth:`predict` advances time, :meth:`update` takes ``z = [1]`` on a heel strike (``None`` skips).
    As a stack estimator (``tbe``): :meth:`step` on the heel-strike channel.

    Attributes:
        x: ``[phase, phase_rate]``.
    """

    name = "tbe"
    inputs: tuple[str, ...] = (HEEL_STRIKE,)
    optional_inputs: tuple[str, ...] = ()
    outputs: tuple[Output, ...] = (("phase", "1"), ("phase_rate", "1/s"))
    tunables: tuple[str, ...] = ("initial_period", "min_period", "max_period")

    def __init__(
        self,
        initial_period: float = 1.0,
        min_period: float = 0.4,
        max_period: float = 4.0,
        max_gap_s: float = MAX_GAP_S,
    ):
        self.initial_period = initial_period
        self.min_period, self.max_period = min_period, max_period
        self.max_gap_s = max_gap_s
        self._t: float | None = None
        self._start()

    def _start(self) -> None:
        self.period = self.initial_period
        self.t = 0.0
        self._last_hs = 0.0
        self._seen_hs = False
        self.x = np.array([0.0, 1.0 / self.initial_period])

    def reset(self) -> None:
        self._start()
        self._t = None

    def retune(self, **params: float) -> None:
        """Change the initial period or the plausible range of measured periods (s)."""
        check_params(self, params)
        initial = float(params.get("initial_period", self.initial_period))
        lo = float(params.get("min_period", self.min_period))
        hi = float(params.get("max_period", self.max_period))
        if not 0 < lo <= initial <= hi:
            raise ValueError(f"periods must satisfy 0 < min <= initial <= max, got {lo}, {initial}, {hi}")
        self.initial_period, self.min_period, self.max_period = initial, lo, hi

    @property
    def state(self) -> NDArray[np.float64]:
        return self.x

    @property
    def covariance(self) -> None:
        return None

    def step(self, t: float, z: NDArray[np.float64]) -> NDArray[np.float64]:
        """The stack interface: ``z = [heel strike]``; returns phase and phase rate. Same order as the
        pipeline: predict over ``dt``, then the heel strike."""
        dt, restart = elapsed(self._t, t, self.max_gap_s)
        if restart:
            self._start()
        self._t = t
        if dt > 0:
            self.predict(dt)
        if z[0] > 0.5:
            self.update(_HS)
        return self.x.copy()

    def predict(self, dt: float) -> None:
        self.t += dt
        self._refresh()

    def update(self, z: Array | None) -> None:
        if z is None or not z[0] > 0.5:
            return
        if self._seen_hs:
            period = self.t - self._last_hs
            if self.min_period <= period <= self.max_period:
                self.period = period
        self._seen_hs = True
        self._last_hs = self.t
        self._refresh()

    def _refresh(self) -> None:
        self.x[0] = ((self.t - self._last_hs) / self.period) % 1.0
        self.x[1] = 1.0 / self.period

    @property
    def phase(self) -> float:
        return float(self.x[0])


#: The timing-based estimate as a session and the views know it (:mod:`gaitscope.estimators.descriptor`).
DESCRIPTOR: Final = Descriptor(
    name=TimingBasedEstimator.name,
    label="Timing-based estimate",
    inputs=TimingBasedEstimator.inputs,
    optional_inputs=TimingBasedEstimator.optional_inputs,
    outputs=(
        out("phase", "1", "gait phase, 0 at heel strike, 1 at the next"),
        out("phase_rate", "1/s", "gait cycles per second"),
    ),
    quantities={"phase": "phase", "phase_rate": "phase_rate"},
    tunables=(Tunable("initial_period"), Tunable("min_period"), Tunable("max_period")),
    purpose="Gait phase from heel-strike timing alone (the last stride's duration): the baseline the filters beat.",
    paper="Medrano et al., IEEE T-RO 2023 (seed 000)",
)

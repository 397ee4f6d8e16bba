"""A toy estimator, as docs/adding_an_estimator.md adds one: the cadence from the heel strikes.

Its descriptor beside its class; ``tests/sessions/test_toy_estimator.py`` registers it (its one line in
``gaitscope.sessions.registry.DESCRIPTORS``, for the test's time) and finds it in a session's stream, the trial's
recording, a review re-run and ``wire.js``.
"""

from __future__ import annotations

from typing import Final

import numpy as np
from numpy.typing import NDArray

from gaitscope.estimators.descriptor import Descriptor, PlotHint, out
from gaitscope.estimators.protocol import HEEL_STRIKE, MAX_GAP_S, Output, check_params, elapsed

__all__ = ["DESCRIPTOR", "ToyCadence"]


class ToyCadence:
    """Strides per minute from the interval between the last two heel strikes (0 before the second one).

    ``state`` is ``[cadence]``; no covariance.
    """

    name = "toy_cadence"
    inputs: tuple[str, ...] = (HEEL_STRIKE,)
    optional_inputs: tuple[str, ...] = ()
    outputs: tuple[Output, ...] = (("cadence_spm", "1/min"),)
    tunables: tuple[str, ...] = ()
    covariance = None

    def __init__(self) -> None:
        self.reset()

    @property
    def state(self) -> NDArray[np.float64]:
        return np.array([self._cadence])

    def reset(self) -> None:
        self._t: float | None = None
        self._last_hs: float | None = None
        self._cadence = 0.0

    def retune(self, **params: float) -> None:
        check_params(self, params)

    def step(self, t: float, z: NDArray[np.float64]) -> NDArray[np.float64]:
        _, restart = elapsed(self._t, t, MAX_GAP_S)
        if restart:
            self.reset()
        self._t = t
        if z[0] == 1.0:
            if self._last_hs is not None:
                self._cadence = 60.0 / (t - self._last_hs)
            self._last_hs = t
        return np.array([self._cadence])


#: The toy as a session and the views know it: one plotted output.
DESCRIPTOR: Final = Descriptor(
    name=ToyCadence.name,
    label="Toy cadence",
    inputs=ToyCadence.inputs,
    outputs=(out("cadence_spm", "1/min", "strides per minute over the last stride"),),
    plots=(PlotHint("toy_cadence", "Toy: cadence", "strides/min", ("cadence_spm",)),),
)

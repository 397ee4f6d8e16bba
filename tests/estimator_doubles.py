"""Test doubles of :class:`gaitscope.estimators.protocol.Estimator`: a timing-based phase, shifted if asked, that
breaks on cue (raises, returns NaN, or lets its covariance diverge after ``n`` samples); and registering an
estimator for one test (:func:`register`: its line in ``gaitscope.sessions.registry.DESCRIPTORS``)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray

from gaitscope.estimators.descriptor import Descriptor, out
from gaitscope.estimators.protocol import HEEL_STRIKE, Output, check_params
from gaitscope.estimators.tbe import TimingBasedEstimator


class Scripted:
    """A stack estimator for tests.

    Args:
        name: its name in the stack.
        shift: added to the timing-based phase (mod 1): a phase estimate far from the others.
        raise_after, nan_after, diverge_after: break after this many samples (None: never).
    """

    inputs: tuple[str, ...] = (HEEL_STRIKE,)
    optional_inputs: tuple[str, ...] = ()
    outputs: tuple[Output, ...] = (("phase", "1"), ("phase_rate", "1/s"))
    tunables: tuple[str, ...] = ()

    def __init__(
        self,
        name: str,
        *,
        shift: float = 0.0,
        raise_after: int | None = None,
        nan_after: int | None = None,
        diverge_after: int | None = None,
    ):
        self.name = name
        self.shift = shift
        self.raise_after, self.nan_after, self.diverge_after = raise_after, nan_after, diverge_after
        self._tbe = TimingBasedEstimator()
        self.P = 1e-3 * np.eye(2)
        self.samples = 0

    @property
    def state(self) -> NDArray[np.float64]:
        return self._tbe.x

    @property
    def covariance(self) -> NDArray[np.float64]:
        return self.P

    def reset(self) -> None:
        self._tbe.reset()
        self.P = 1e-3 * np.eye(2)
        self.samples = 0

    def retune(self, **params: float) -> None:
        check_params(self, params)

    def step(self, t: float, z: NDArray[np.float64]) -> NDArray[np.float64]:
        self.samples += 1
        if self.raise_after is not None and self.samples > self.raise_after:
            raise RuntimeError("boom")
        y = self._tbe.step(t, z)
        y[0] = (y[0] + self.shift) % 1.0
        if self.nan_after is not None and self.samples > self.nan_after:
            y[0] = math.nan
        if self.diverge_after is not None and self.samples > self.diverge_after:
            self.P *= 100.0
        return y


def scripted(name: str, **kw: Any) -> Descriptor:
    """The descriptor of a :class:`Scripted` double called ``name`` (``kw``: its arguments), built by the registry."""
    return Descriptor(
        name=name,
        label=f"Scripted double {name}",
        inputs=Scripted.inputs,
        outputs=(out("phase", "1", "the timing-based phase, shifted"), out("phase_rate", "1/s", "its rate")),
        quantities={"phase": "phase", "phase_rate": "phase_rate"},
    ).built_by(lambda ctx: Scripted(name, **kw))


def register(monkeypatch: pytest.MonkeyPatch, descriptor: Descriptor) -> None:
    """Register ``descriptor`` for this test, as its line in the registry would: it replaces the registered
    one of its name, else comes last. Everything read from the registry sees it until the test ends."""
    from gaitscope.sessions import registry

    names = [d.name for d in registry.DESCRIPTORS]
    if descriptor.name in names:
        listed = [descriptor if d.name == descriptor.name else d for d in registry.DESCRIPTORS]
    else:
        listed = [*registry.DESCRIPTORS, descriptor]
    monkeypatch.setattr(registry, "DESCRIPTORS", listed)

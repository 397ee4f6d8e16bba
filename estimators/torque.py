"""Biomimetic ankle torque profile (seed 000 section II-F).

The paper fits a regressor "near-identical" to the gait model to the ankle moment, scales it down by 5
and applies plantarflexion only; the authors' code uses a piecewise Bernstein basis instead. Gaitscope
follows the paper's text: the same Kronecker regressor as the gait model (Fourier order
``torque_order``, default 20) fitted to the plantarflexor moment per kilogram, with the gait model's
``l = 0`` constraint (no assistance when standing still). At run time::

    tau = clip(scale * mass * model(p, l, r), 0, max_torque)   if p <= cutoff_phase
    tau = 0                                                    otherwise (and for a NaN state)

with ``scale = 1/5`` and ``cutoff_phase = 0.65`` (the code's runtime rule). Positive is plantarflexion.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from gaitscope.estimators import _kernels
from gaitscope.estimators.basis import Array, n_terms
from gaitscope.estimators.gait_model import OUT_HEEL_UP, Gram, evaluate, gait_constraints, solve_constrained


def fit_torque(g: Gram, order: int) -> Array:
    """Fit the plantarflexor moment per kg from a one-output Gram; coefficients ``(2, 2, 2N+1)``."""
    C, d = gait_constraints(order, OUT_HEEL_UP)  # all outputs but the foot share "0 at l = 0"
    return solve_constrained(g.G, g.b[:, 0], C, d).reshape(2, 2, n_terms(order))


@dataclass(frozen=True)
class TorqueProfile:
    """Ankle assistance as a function of phase, stride length (leg lengths) and incline (deg).

    Attributes:
        coef: ``(2, 2, 2N+1)`` model of the plantarflexor moment in N m/kg.
        scale: fraction of the biological moment applied (paper: 1/5).
        cutoff_phase: no torque after this phase (paper's code: 0.65).
    """

    coef: Array
    scale: float = 0.2
    cutoff_phase: float = 0.65

    def biological(self, p: Array, l: Array, r: Array) -> Array:
        """The fitted plantarflexor moment per kg at arrays of states."""
        return evaluate(self.coef[None], p, l, r)[:, 0]

    def torque(self, p: Array, l: Array, r: Array, mass_kg: float, max_torque: float = np.inf) -> Array:
        """Commanded plantarflexion torque (N m) at arrays of states, vectorised."""
        tau = self.scale * mass_kg * self.biological(p, l, r)
        tau = np.where((np.asarray(p) % 1.0 <= self.cutoff_phase) & np.isfinite(tau), tau, 0.0)
        return np.clip(tau, 0.0, max_torque)

    def torque_at(self, p: float, l: float, r: float, mass_kg: float, max_torque: float = np.inf) -> float:
        """Scalar :meth:`torque` for the streaming path; 0 for a non-finite state or result."""
        if not p % 1.0 <= self.cutoff_phase:  # NaN phase fails too
            return 0.0
        coef4, _ = self._workspace
        tau = self.scale * mass_kg * _kernels.model_value(coef4, 0, p, l, r)  # model_terms' h, without derivatives
        if not math.isfinite(tau):
            return 0.0
        return float(min(max(tau, 0.0), max_torque))

    @functools.cached_property
    def _workspace(self) -> tuple[Array, Array]:
        """Contiguous ``(1, 2, 2, K)`` coefficients and a ``(1, 7)`` scratch row for the kernel."""
        return np.ascontiguousarray(self.coef[None]), np.empty((1, 7))

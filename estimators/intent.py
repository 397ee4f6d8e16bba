"""Speed-change intent: the buttressed Kalman filter of Karulkar and Wensing (seed 001).

The state is the centre of mass relative to the stance foot and the walker's desired forward speed,
``z = [p_x, p_y, p_z, v_x, v_y, v_z, v_x^d]`` (m, m/s), estimated twice per step (seed 001 Sec. II-A):

- at **touchdown** a Bayesian update on the step length just taken, through the step-length model
  ``l_step = [v_x, v_x^d - v_x, l_leg] kappa`` (eq. 1) at the state of the last mid-stance (eqs. 2-4),
  with process noise ``Q_T`` added to the covariance inside the innovation only (as eq. 2 writes it);
  for a user with an incomplete spinal cord injury, optionally also the RMS hip-motor current of the
  swing, ``I = [v_x, v_x^d - v_x] alpha``;
- from touchdown to the next **mid-stance** the stance foot changes: ``z <- D z``, ``P <- D P D^T + Q_M``
  with ``D = diag(1, -1, 1, 1, -1, 1, 1)`` (eqs. 5-6);
- at **mid-stance** a Kalman update on the measured centre-of-mass position and velocity, ``H_M = [I_6 0]``
  (eqs. 7-9).

Intent is the change of ``v_x^d`` from one mid-stance to the next (speed up > 0, slow down < 0), read as
soon as the touchdown has updated it (seed 001 Fig. 6: "the intent of the user as inferred at TD"), a
quarter step before the mid-stance whose speed it anticipates (``BKFConfig.intent_at``).

Choices where the paper is silent (parameters; ``docs/estimators.md``):

- The touchdown update linearises eq. 1 at the last mid-stance's ``v_x`` and ``v_x^d``; eq. 1 is linear in
  them, so this is exact.
- A touchdown without a mid-stance since the last one (a doubled touchdown) is ignored; a mid-stance
  without a touchdown since the last (a missed touchdown) propagates and updates without the Bayesian
  step, so the intent of that step is 0 and its confidence low.
- Initial state: the first mid-stance's measurement with ``v_x^d = v_x``, covariance ``P0``; it needs the
  sagittal entries (forward and vertical position, forward velocity); a lateral one not measured (as
  from sagittal leg kinematics, :mod:`gaitscope.estimators.com_kinematics`) starts at 0 and is never updated.
- Initial covariance (not given): ``1e-4`` for the CoM states, ``1e-2`` (0.1 m/s SD) for ``v_x^d``
  (``BKFConfig.p0``).
- Confidence of an intent: ``|delta v_x^d| / sqrt(var(v_x^d))``, the change in standard deviations of the
  desired speed (a z-score); the paper reports no confidence.

The filter on a sample stream (events, holds on bad input) is :class:`estimators.intent_estimator.IntentEstimator`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Final, Literal

import numpy as np
from numpy.typing import NDArray

__all__ = ["COHORT", "ISCI", "UNINJURED", "BKFConfig", "ButtressedKF", "D", "fit_alpha", "fit_kappa"]

Array = NDArray[np.float64]

#: Propagation from touchdown to the next mid-stance: the stance foot changes side (eq. 5).
D: Final = np.diag([1.0, -1.0, 1.0, 1.0, -1.0, 1.0, 1.0])
_VX, _VXD = 3, 6


@dataclass(frozen=True)
class BKFConfig:
    """Tuning of :class:`ButtressedKF` (seed 001 Sec. III; the digest in ``shared/reference/estimators.md``).

    Attributes:
        kappa: step-length model coefficients of ``[v_x, v_x^d - v_x, l_leg]`` (eq. 1).
        alpha: hip-current model coefficients of ``[v_x, v_x^d - v_x]`` (iSCI variant), None: not used.
        q_t: touchdown process noise (added to ``P`` in the innovation, eq. 2), a scalar times ``I_7``.
        r_t: touchdown measurement variance: step length, and the current when ``alpha`` is given.
        q_m: propagation noise ``Q_M`` diagonal (eq. 6).
        r_m: mid-stance measurement noise ``R_M`` diagonal.
        p0: initial variances of the state.
        intent_at: where the intent is read: ``"touchdown"`` (the default: desired speed after the
            touchdown update minus that after the last mid-stance, seed 001 Fig. 6's "intent inferred at
            TD", a quarter step before the mid-stance) or ``"midstance"`` (the change from mid-stance to
            mid-stance, Sec. II-C's wording). At a mid-stance the touchdown's intent holds.
    """

    kappa: tuple[float, float, float] = (0.3325, 0.2635, 0.3757)
    alpha: tuple[float, float] | None = None
    q_t: float = 1e-4
    r_t: tuple[float, ...] = (1e-5,)
    q_m: tuple[float, ...] = tuple(1e-4 * np.array([1, 1, 1, 1, 1, 1, 10.0]))
    r_m: tuple[float, ...] = tuple(1e-10 * np.array([1e4, 1e4, 1e4, 1e5, 1, 1]))
    p0: tuple[float, ...] = (1e-4,) * 6 + (1e-2,)
    intent_at: Literal["touchdown", "midstance"] = "touchdown"


#: The paper's uninjured tuning.
UNINJURED: Final = BKFConfig()
#: The paper's tuning for users with an incomplete spinal cord injury (with the hip-current model).
ISCI: Final = BKFConfig(kappa=(0.0818, 0.0551, 0.4045), alpha=(8.6067, 4.2420), q_t=1e-3, r_t=(1e-4, 1e-4))
#: For a new walker with no training of their own (beyond the paper): the step-length model regressed on
#: the virtual cohort's speed-change walks with seed 001's labels, the paper's uninjured noise otherwise.
#: Source: ``gaitscope crossval --study intent`` ("the cohort's kappa", ``docs/results.md``); seed 001's
#: kappa came from one Ekso GT user, whose steps are shorter than unassisted walking's.
COHORT: Final = BKFConfig(kappa=(0.2420, 0.3557, 0.4193))


@dataclass
class ButtressedKF:
    """The buttressed Kalman filter (see the module docstring): :meth:`touchdown`, :meth:`midstance`.

    Attributes:
        z, P: the state and its covariance (after the last event).
        intent: ``v_x^d`` change over the step since the last mid-stance (m/s), read at the touchdown
            (``BKFConfig.intent_at``); 0 for a step without a touchdown.
        confidence: that change in standard deviations of ``v_x^d`` (0 when unknown).
    """

    leg_length: float
    config: BKFConfig = field(default_factory=BKFConfig)
    z: Array = field(init=False)
    P: Array = field(init=False)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.leg_length) and 0.3 <= self.leg_length <= 1.5):
            raise ValueError(f"leg length must be 0.3..1.5 m, got {self.leg_length}")
        self.reset()

    def reset(self) -> None:
        self.z = np.zeros(7)
        self.P = np.diag(self.config.p0)
        self.started = False
        self._touched = False  # a touchdown update since the last mid-stance
        self._last_vxd: float | None = None
        self.intent = 0.0
        self.confidence = 0.0

    # --- touchdown ------------------------------------------------------------------------------
    def touchdown_model(self) -> tuple[Array, Array]:
        """Predicted touchdown measurements (step length, and hip current when modelled) and their
        Jacobian ``(m, 7)`` at the state."""
        k1, k2, k3 = self.config.kappa
        vx, vxd = self.z[_VX], self.z[_VXD]
        rows = [(vx * k1 + (vxd - vx) * k2 + self.leg_length * k3, k1 - k2, k2)]
        if self.config.alpha is not None:
            a1, a2 = self.config.alpha
            rows.append((vx * a1 + (vxd - vx) * a2, a1 - a2, a2))
        y = np.array([r[0] for r in rows])
        H = np.zeros((len(rows), 7))
        for i, (_, d_vx, d_vxd) in enumerate(rows):
            H[i, _VX], H[i, _VXD] = d_vx, d_vxd
        return y, H

    def touchdown(self, step_length_m: float, hip_current_a: float = math.nan) -> bool:
        """The Bayesian update of eqs. 2-4 on the step just taken; False when skipped (before the first
        mid-stance, a second touchdown in one step, or a non-finite step length)."""
        if not self.started or self._touched or not math.isfinite(step_length_m):
            return False
        y_hat, H = self.touchdown_model()
        y = [step_length_m]
        r = list(self.config.r_t[:1])
        if self.config.alpha is not None and math.isfinite(hip_current_a):
            y.append(hip_current_a)
            r.append(self.config.r_t[-1])
        m = len(y)
        H, y_hat = H[:m], y_hat[:m]
        S = H @ (self.P + self.config.q_t * np.eye(7)) @ H.T + np.diag(r)
        PHt = self.P @ H.T
        gain = np.linalg.solve(S, PHt.T).T
        self.z = self.z + gain @ (np.array(y) - y_hat)
        self.P = self.P - gain @ H @ self.P
        self.P = (self.P + self.P.T) / 2.0
        self._touched = True
        if self.config.intent_at == "touchdown":
            self._set_intent()
        return True

    def _set_intent(self) -> None:
        """Intent: the desired speed now minus after the last mid-stance; confidence in its SDs now."""
        vxd = float(self.z[_VXD])
        self.intent = vxd - (self._last_vxd if self._last_vxd is not None else vxd)
        self.confidence = abs(self.intent) / math.sqrt(max(float(self.P[_VXD, _VXD]), 1e-18))

    # --- mid-stance -----------------------------------------------------------------------------
    def midstance(self, com: Array) -> float:
        """Propagate to this mid-stance (eqs. 5-6) and update on the measured ``[p_CoM, v_CoM]`` relative
        to the new stance foot (eqs. 7-9); returns the intent (change of ``v_x^d``, m/s).

        A measurement with a non-finite entry skips the update of that entry (a lost channel)."""
        com = np.asarray(com, dtype=np.float64).reshape(6)
        c = self.config
        if not self.started:
            if not np.isfinite(com[[0, 2, 3]]).all():  # the sagittal entries; lateral ones may be unknown
                return 0.0
            self.z = np.where(np.isfinite(np.r_[com, com[3]]), np.r_[com, com[3]], 0.0)
            self.P = np.diag(c.p0)
            self.started, self._touched = True, False
            self._last_vxd = float(self.z[_VXD])
            self.intent = self.confidence = 0.0
            return 0.0
        self.z = D @ self.z
        self.P = D @ self.P @ D.T + np.diag(c.q_m)
        ok = np.isfinite(com)
        if ok.any():
            H = np.eye(6, 7)[ok]
            S = H @ self.P @ H.T + np.diag(np.asarray(c.r_m)[ok])
            K = np.linalg.solve(S, H @ self.P).T
            self.z = self.z + K @ (com[ok] - H @ self.z)
            self.P = (np.eye(7) - K @ H) @ self.P
            self.P = (self.P + self.P.T) / 2.0
        if not self._touched:
            self.intent = self.confidence = 0.0
        elif self.config.intent_at == "midstance":
            self._set_intent()
        self._last_vxd = float(self.z[_VXD])
        self._touched = False
        return self.intent

    @property
    def desired_speed(self) -> float:
        return float(self.z[_VXD])

    @property
    def touched(self) -> bool:
        """A touchdown update since the last mid-stance (the next mid-stance will have an intent)."""
        return self._touched


# --- the models' regressions (seed 001 Sec. III-A) --------------------------------------------------------
Steps = tuple[Array, Array, Array]


def fit_kappa(walks: Sequence[Steps], leg_length_m: Sequence[float]) -> Array:
    """Eq. 1 by least squares with seed 001's labels: ``l_(k+1) = [v_k, v_(k+1) - v_k, l_leg] kappa`` over
    the steps of every walk, each ``(v_k, v_(k+1), l_(k+1))`` (speeds at consecutive mid-stances and the
    step between them) with its walker's leg length (for one walker it acts as the intercept)."""
    rows = [
        np.column_stack([v0, v1 - v0, np.full(len(v0), leg)])
        for (v0, v1, _), leg in zip(walks, leg_length_m, strict=True)
    ]
    return _lstsq(rows, [w[2] for w in walks], "kappa")


def fit_alpha(walks: Sequence[Steps]) -> Array:
    """The iSCI variant's current model (seed 001 eq. 14) by least squares with the same labels:
    ``I_(k+1) = [v_k, v_(k+1) - v_k] alpha`` over every walk's ``(v_k, v_(k+1), I_(k+1))``, ``I`` the RMS
    hip-motor current of the swing before touchdown ``k+1`` (A)."""
    rows = [np.column_stack([v0, v1 - v0]) for v0, v1, _ in walks]
    return _lstsq(rows, [w[2] for w in walks], "alpha")


def _lstsq(rows: list[Array], y: list[Array], what: str) -> Array:
    a, b = np.vstack(rows), np.concatenate(y)
    ok = np.isfinite(a).all(axis=1) & np.isfinite(b)
    if ok.sum() < a.shape[1] + 1:
        raise ValueError(f"need at least {a.shape[1] + 1} steps with finite values to fit {what}, got {ok.sum()}")
    coef: Array = np.asarray(np.linalg.lstsq(a[ok], b[ok], rcond=None)[0], dtype=np.float64)
    return coef

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

Intent is the change of ``v_x^d`` from one mid-stance to the next (speed up > 0, slow down < 0).

Choices where the paper is silent (parameters; ``docs/estimators.md``):

- The touchdown update linearises eq. 1 at the last mid-stance's ``v_x`` and ``v_x^d``; eq. 1 is linear in
  them, so this is exact.
- A touchdown without a mid-stance since the last one (a doubled touchdown) is ignored; a mid-stance
  without a touchdown since the last (a missed touchdown) propagates and updates without the Bayesian
  step, so the intent of that step is 0 and its confidence low.
- Initial state: the first mid-stance's measurement with ``v_x^d = v_x``, covariance ``P0``.
- Initial covariance (not given): ``1e-4`` for the CoM states, ``1e-2`` (0.1 m/s SD) for ``v_x^d``
  (``BKFConfig.p0``).
- Confidence of an intent: ``|delta v_x^d| / sqrt(var(v_x^d))``, the change in standard deviations of the
  desired speed (a z-score); the paper reports no confidence.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Final

import numpy as np
from numpy.typing import NDArray

from estimators.protocol import check_params, elapsed

__all__ = ["ISCI", "UNINJURED", "BKFConfig", "ButtressedKF", "D"]

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
    """

    kappa: tuple[float, float, float] = (0.3325, 0.2635, 0.3757)
    alpha: tuple[float, float] | None = None
    q_t: float = 1e-4
    r_t: tuple[float, ...] = (1e-5,)
    q_m: tuple[float, ...] = tuple(1e-4 * np.array([1, 1, 1, 1, 1, 1, 10.0]))
    r_m: tuple[float, ...] = tuple(1e-10 * np.array([1e4, 1e4, 1e4, 1e5, 1, 1]))
    p0: tuple[float, ...] = (1e-4,) * 6 + (1e-2,)


#: The paper's uninjured tuning.
UNINJURED: Final = BKFConfig()
#: The paper's tuning for users with an incomplete spinal cord injury (with the hip-current model).
ISCI: Final = BKFConfig(kappa=(0.0818, 0.0551, 0.4045), alpha=(8.6067, 4.2420), q_t=1e-3, r_t=(1e-4, 1e-4))


@dataclass
class ButtressedKF:
    """The buttressed Kalman filter (see the module docstring): :meth:`touchdown`, :meth:`midstance`.

    Attributes:
        z, P: the state and its covariance (after the last event).
        intent: ``v_x^d`` change over the last mid-stance to mid-stance step (m/s).
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
        return True

    # --- mid-stance -----------------------------------------------------------------------------
    def midstance(self, com: Array) -> float:
        """Propagate to this mid-stance (eqs. 5-6) and update on the measured ``[p_CoM, v_CoM]`` relative
        to the new stance foot (eqs. 7-9); returns the intent (change of ``v_x^d``, m/s).

        A measurement with a non-finite entry skips the update of that entry (a lost channel)."""
        com = np.asarray(com, dtype=np.float64).reshape(6)
        c = self.config
        if not self.started:
            if not np.isfinite(com).all():
                return 0.0
            self.z = np.array([*com, com[3]])
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
        vxd = float(self.z[_VXD])
        touched = self._touched
        self.intent = vxd - (self._last_vxd if self._last_vxd is not None else vxd) if touched else 0.0
        sd = math.sqrt(max(float(self.P[_VXD, _VXD]), 1e-18))
        self.confidence = abs(self.intent) / sd if touched else 0.0
        self._last_vxd = vxd
        self._touched = False
        return self.intent

    @property
    def desired_speed(self) -> float:
        return float(self.z[_VXD])


#: Channels the stack's intent estimator reads (SensorFrame wire names).
COM_CHANNELS: Final = (
    "com_forward_m",
    "com_lateral_m",
    "com_up_m",
    "com_forward_vel_m_s",
    "com_lateral_vel_m_s",
    "com_up_vel_m_s",
)


class IntentEstimator:
    """The buttressed Kalman filter as a stack estimator (``intent``): events from the sample stream.

    - Touchdown (seed 001 Sec. II-B): both feet's vertical force above ``contact_fraction`` of the largest
      force seen so far (5 %), or both contact flags when a device sends them; the rising edge of that
      double support is a touchdown, and the step length is the frame's ``step_length_m`` there.
    - Mid-stance: a zero crossing of ipsilateral minus contralateral hip angle.
    - Between events the outputs hold: desired speed, intent (the last mid-stance's change of desired
      speed), its class (``intent_code``: 1 speeding up, -1 slowing down, 0 steady, when the change is
      below ``deadband_m_s`` or its confidence below ``min_confidence`` standard deviations) and
      confidence. The bookkeeping of a sample between events is a few comparisons.
    - The hip-motor current (``motor_current_A``, optional) feeds the iSCI variant's current model when
      the configuration has ``alpha``: its RMS over the swing before the touchdown.
    """

    name = "intent"
    inputs: tuple[str, ...] = (*COM_CHANNELS, "hip_angle_deg", "hip_angle_contra_deg", "foot_force_N",
                               "foot_force_contra_N", "step_length_m")  # fmt: skip
    optional_inputs: tuple[str, ...] = ("foot_contact", "foot_contact_contra", "motor_current_A")
    outputs: tuple[tuple[str, str], ...] = (
        ("desired_speed_m_s", "m/s"),
        ("intent_m_s", "m/s"),
        ("intent_code", "code"),
        ("intent_confidence", "1"),
        ("speed_m_s", "m/s"),
    )
    tunables: tuple[str, ...] = ("deadband_m_s", "min_confidence")

    def __init__(
        self,
        leg_length: float,
        config: BKFConfig = UNINJURED,
        contact_fraction: float = 0.05,
        deadband_m_s: float = 0.01,
        min_confidence: float = 1.0,
    ):
        self.filter = ButtressedKF(leg_length, config)
        self.contact_fraction = contact_fraction
        self.deadband_m_s, self.min_confidence = deadband_m_s, min_confidence
        self.reset()

    @property
    def state(self) -> Array:
        return self.filter.z

    @property
    def covariance(self) -> Array:
        return self.filter.P

    def reset(self) -> None:
        self.filter.reset()
        self._t: float | None = None
        self._max_force = 0.0
        self._double = False
        self._hip_diff = math.nan
        self._current_sq, self._current_n = 0.0, 0
        self._out = np.zeros(5)

    def retune(self, **params: float) -> None:
        check_params(self, params)
        for k, v in params.items():
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{k} must be a number >= 0, got {v}")
        self.deadband_m_s = float(params.get("deadband_m_s", self.deadband_m_s))
        self.min_confidence = float(params.get("min_confidence", self.min_confidence))

    def step(self, t: float, z: Array) -> Array:
        """One sample: ``z`` = the six CoM channels, both hip angles, both foot forces, the last step length,
        then the optional contact flags and motor current (NaN: missing)."""
        _, restart = elapsed(self._t, t)
        if restart:  # a pause: the walk starts over
            self.reset()
        self._t = t
        f_i, f_c, contact_i, contact_c = z[8], z[9], z[11], z[12]
        for f in (f_i, f_c):
            if f > self._max_force:  # NaN compares False
                self._max_force = f
        if contact_i == contact_i and contact_c == contact_c:  # both flags sent (not NaN)
            double = contact_i > 0.5 and contact_c > 0.5
        else:
            limit = self.contact_fraction * self._max_force
            double = self._max_force > 0 and f_i > limit and f_c > limit
        current = z[13]
        if current == current and not double:
            self._current_sq += current * current
            self._current_n += 1
        if double and not self._double:
            rms = math.sqrt(self._current_sq / self._current_n) if self._current_n else math.nan
            self.filter.touchdown(float(z[10]), rms)
            self._current_sq, self._current_n = 0.0, 0
        self._double = double
        diff = z[6] - z[7]
        if diff == diff:
            if self._hip_diff == self._hip_diff and (diff > 0) != (self._hip_diff > 0):
                self.filter.midstance(z[:6])
                self._classify()
            self._hip_diff = diff
        return self._out.copy()

    def _classify(self) -> None:
        f = self.filter
        code = 0.0
        if abs(f.intent) >= self.deadband_m_s and f.confidence >= self.min_confidence:
            code = 1.0 if f.intent > 0 else -1.0
        self._out[:] = (f.desired_speed, f.intent, code, f.confidence, float(f.z[_VX]))

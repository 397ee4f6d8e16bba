"""SDRE joint-angle estimator and its comparators (Zhong 2016 MS thesis, seed 002, chapter 4).

The State-Dependent Riccati Equation (SDRE) estimator writes a leg model ``x' = f(x, u)`` with IMU
measurements ``y = h(x)`` in state-dependent coefficient (SDC) form, ``f = A(x) x + B(x) u`` and
``h = C(x) x``, and runs a Kalman-Bucy-like observer with those matrices (eqs. 4.14-4.16):

    xhat' = A xhat + B u + K (y - C xhat),  K = P C^T S^-1,
    P'    = A P + P A^T + 2 a P - P C^T S^-1 C P + Q,   a = 1

(the thesis prints ``C^T S^-1 C^T``: a typo). Two models:

- **seated knee** (section 4.1, eqs. 4.1-4.13): ``x = [theta + theta_eq, thetadot]``, the shank's angle
  from the vertical (forward positive) and its rate; knee angle ``phi = pi/2 - x1`` (thigh horizontal);
  ``x2' = -beta sin x1 + alpha (T_p + T_ke)`` with the passive torque ``T_p`` (eq. 4.2) and the FES torque
  ``T_ke = (c2 phi^2 + c1 phi + c0)(1 + c3 phidot) u`` (eq. 4.3); ``y = [gyro, -g sin x1]``;
  ``A = [[0, 1], [-beta sinc x1, 0]]``, ``C = [[0, 1], [-g sinc x1, 0]]``, ``B u = [0, alpha (T_p + T_ke)]``
  (the torques evaluated at the estimate). Parameters: the thesis's Table 1 (:data:`TABLE1`), with ``J``,
  ``m`` and ``l_c``, which it does not give, from Winter (2009) (:meth:`KneeParams.from_table1`).
- **fixed-hip thigh and shank** (section 4.2, eqs. 4.18-4.25): ``x = [q1, q2, q1', q2']``, the thigh's
  and shank's absolute angles from the vertical; ``M(q) q'' + V + G = T_pa + T`` of a double pendulum,
  ``M = [[m11, a1 cos(q1 - q2)], [a1 cos(q1 - q2), m22]]``, ``V = [a1 q2'^2 s, -a1 q1'^2 s]``,
  ``G = [b2 sin q1, b3 sin q2]``, ``s = sin(q1 - q2)``; ``y = [q1', q2', -g sin q1, -g sin q2]``; SDC rows
  as corrected in ``shared/reference/estimators.md`` section 5. Knee flexion is ``q1 - q2``.

The integration (both models, and the EKF) is :mod:`gaitscope.estimators._sdre_kernel` (numba);
:class:`ContinuousFilter` with ``compiled=False`` is the same maths in plain numpy, the test oracle.

Speed (issue #24, what ``sdre_knee`` runs): the estimator has no Riccati *solve* to replace. The thesis's
SDRE integrates the differential Riccati equation with the estimate (eq. 4.16), and a solve of the
algebraic equation at each sample (``scipy.linalg.solve_continuous_are``, or a closed form, which the
thesis does not give and which would exist only for the 1-DOF knee) is another estimator, whose ``P``
and gain differ from the integrated ones by far more than 1e-9. So the integration stays and is made
cheaper: the two-link SDRE's RK4 (:func:`~gaitscope.estimators._sdre_kernel.two_link_sdre_rk4`) allocates its
stages once per sample, not per stage, shares the model's sines between ``f`` and the SDC pair and
skips the products with ``Am``'s and ``Cm``'s structural zeros and ones; it performs the same
operations on the same values in the same order as the generic kernel (kept as
:func:`~gaitscope.estimators._sdre_kernel.rk4`, the reference for it and the path of the knee model and the EKF),
so its estimates are the generic kernel's to the bit on finite values
(``tests/estimators/test_sdre.py``: a simulated walk, sample by sample, to 1e-9).

Comparators as published: the **EKF** is the same observer with the Jacobians of ``f`` and ``h`` in place
of the SDC pair (``jacobian=True``) and ``a = 0`` (a standard continuous EKF; the thesis gives no ``a``
for it); the **rotation-matrix method** (RMX) takes each IMU's orientation and the knee angle from the
relative rotation of the shank's frame in the thigh's (:func:`rmx_knee_angle`).

Choices where the thesis is silent or inconsistent (parameters; defaults in brackets):

- ``J``, ``m``, ``l_c`` (not in Table 1): Winter (2009) Table 4.1, leg and foot: mass 0.061 of body mass,
  centre of mass 0.606 of the segment from the knee, radius of gyration 0.416 about it; shank length
  0.246 of height; thigh: 0.100, 0.433, 0.323, length 0.245 of height. Subject height and mass are not
  given: [1.75 m, 75 kg].
- Table 1's columns are taken in Table 2's order (P1-L, P1-R, P2-L, P2-R, P3-L, P3-R); rows whose cells
  the text extraction merged (d2, d4, d6) are read left to right.
- The EKF's Jacobian includes the derivatives of ``T_p`` and ``T_ke`` (the full Jacobian of ``f``); for
  the two-link model it is taken by central differences (step ``1e-6``).
- Integration: classic RK4 [1 kHz, the digest's rate], ``y`` and ``u`` held over each step (the sample
  that just arrived), ``P`` symmetrised after every step; steps shortened where the equations are stiff
  (small ``S``, large ``P``: :func:`gaitscope.estimators._sdre_kernel.integrate`), which fixed-step RK4 at 1 kHz
  would not survive (the thesis ran Simulink, whose solver it does not name).
- ``S``: the thesis says the sample standard deviation of the resting, filtered IMU data; it is a
  covariance, so the default is the variance (``S`` is a parameter). ``Q`` diagonal, tuned (the thesis
  tuned it on one pre-trial). ``P0`` [identity]; ``x0`` from the resting accelerometer
  (:func:`initial_angle`), rates 0.
- Two-link passive torques: the knee's from Table 1 on the knee angle ``q1 - q2``, none at the hip
  (the thesis gives none); active torques are the known joint torques ``u = [hip, knee]`` (N m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gaitscope.estimators import _sdre_kernel as kernel

__all__ = [
    "TABLE1",
    "ContinuousFilter",
    "G",
    "KneeParams",
    "TwoLinkParams",
    "complementary_angle",
    "initial_angle",
    "rmx_knee_angle",
    "rotation_z",
]

Array = NDArray[np.float64]

#: Gravity (m/s^2).
G: Final = 9.81

#: Winter (2009) Table 4.1: (mass fraction, centre of mass from the proximal joint, radius of gyration about
#: the centre of mass), both as fractions of segment length, and the segment's length as a fraction of height.
WINTER_SHANK: Final = (0.061, 0.606, 0.416, 0.246)  # "leg and foot"; length: knee to ankle
WINTER_THIGH: Final = (0.100, 0.433, 0.323, 0.245)

#: Thesis Table 1 by leg: phi0, d1..d6, c0..c3, theta_eq (rad, N m, N m s, ...), activation time Ta (s).
TABLE1: Final[dict[str, tuple[float, ...]]] = {
    "P1-L": (0.40, 4.05, 3.05, 1.48e-9, 14.10, 8.90, -1.76, 76.71, 3.12, -15.36, 0.28, 0.13, 0.25),
    "P1-R": (8.34e-11, 2.27, 3.30, 3.96e-8, 11.20, 15.30, -1.77, 61.00, -0.57, -8.47, 0.47, 0.08, 0.19),
    "P2-L": (0.78, 5.86, 3.56, 1.54e-5, 8.70, 3.05, -3.45, 27.74, 296.32, -186.11, 1.93e-4, 0.19, 0.14),
    "P2-R": (2.22e-14, 4.12, 2.54, 2.38e-5, 8.33, 5.41, -3.45, -28.29, 402.07, -231.19, 0.88, 0.17, 1.0),
    "P3-L": (0.30, 2.22e-14, 2.54, 6.1984, 0.84, 0.04, -0.41, -17.88, 299.41, -183.75, 1.52, 0.17, 0.72),
    "P3-R": (1.50, 4.41, 3.14, 3.39e-4, 6.70, 0.16, -1.26e-8, 5.63, 159.39, -85.94, 1.75, 0.14, 0.18),
}


@dataclass(frozen=True)
class KneeParams:
    """The seated knee model (eqs. 4.1-4.6). ``d`` = (d1..d6), ``c`` = (c0..c3); SI units, angles in rad."""

    phi0: float
    d: tuple[float, float, float, float, float, float]
    c: tuple[float, float, float, float]
    theta_eq: float
    inertia: float  #: J about the knee (kg m^2)
    mass: float  #: m of shank and foot (kg)
    com: float  #: l_c, knee to centre of mass (m)
    activation_s: float = 0.0  #: Table 1's Ta (the thesis's estimator ignores activation dynamics)
    g: float = G

    @property
    def alpha(self) -> float:
        return 1.0 / self.inertia

    @property
    def beta(self) -> float:
        return self.mass * self.g * self.com / self.inertia

    @classmethod
    def from_table1(cls, leg: str, height_m: float = 1.75, mass_kg: float = 75.0) -> KneeParams:
        """Table 1's leg with ``J``, ``m``, ``l_c`` from Winter (2009) for a subject of this height and mass."""
        phi0, d1, d2, d3, d4, d5, d6, c0, c1, c2, c3, eq, ta = TABLE1[leg]
        frac, com, gyr, length = WINTER_SHANK
        seg, m = length * height_m, frac * mass_kg
        inertia = m * seg**2 * (gyr**2 + com**2)  # parallel axes: about the knee
        return cls(phi0, (d1, d2, d3, d4, d5, d6), (c0, c1, c2, c3), eq, inertia, m, com * seg, ta)

    def vector(self) -> Array:
        """The kernel's parameter vector ``[alpha, beta, g, phi0, d1..d6, c0..c3]``."""
        return np.array([self.alpha, self.beta, self.g, self.phi0, *self.d, *self.c], dtype=np.float64)

    def torques(self, phi: ArrayLike, phidot: ArrayLike, u: ArrayLike) -> Array:
        """``T_p + T_ke`` (N m, extending), eqs. 4.2-4.3."""
        ph, pd, uu = (np.asarray(v, dtype=np.float64) for v in (phi, phidot, u))
        d, c = self.d, self.c
        tp = d[0] * (ph - self.phi0) + d[1] * pd + d[2] * np.exp(d[3] * ph) - d[4] * np.exp(d[5] * ph)
        return np.asarray(tp + (c[2] * ph**2 + c[1] * ph + c[0]) * (1.0 + c[3] * pd) * uu)

    def model(self, x: Array, u: Array, jacobian: bool) -> tuple[Array, Array, Array, Array]:
        """``f(x, u)``, ``h(x)`` and the SDC pair ``(A, C)`` or the Jacobians ``(F, H)`` (numpy reference).

        ``f`` is formed as ``A x + B u`` with the SDC ``A`` (eq. 4.14's form) whichever pair is returned."""
        phi, phidot = math.pi / 2 - x[0], -x[1]
        s = _sinc(x[0])
        a_sdc = np.array([[0.0, 1.0], [-self.beta * s, 0.0]])
        c_sdc = np.array([[0.0, 1.0], [-self.g * s, 0.0]])
        bu = np.array([0.0, self.alpha * float(self.torques(phi, phidot, u[0]))])
        f, h = a_sdc @ x + bu, c_sdc @ x
        if not jacobian:
            return f, h, a_sdc, c_sdc
        d, c, uu = self.d, self.c, u[0]
        dtp = d[0] + d[2] * d[3] * math.exp(d[3] * phi) - d[4] * d[5] * math.exp(d[5] * phi)
        dke = (2 * c[2] * phi + c[1]) * (1 + c[3] * phidot) * uu
        dke_rate = (c[2] * phi**2 + c[1] * phi + c[0]) * c[3] * uu
        jf = np.array(
            [[0.0, 1.0], [-self.beta * math.cos(x[0]) - self.alpha * (dtp + dke), -self.alpha * (d[1] + dke_rate)]]
        )
        jh = np.array([[0.0, 1.0], [-self.g * math.cos(x[0]), 0.0]])
        return f, h, jf, jh


@dataclass(frozen=True)
class TwoLinkParams:
    """The fixed-hip thigh and shank (eq. 4.23): ``M = [[m11, a1 cos], [a1 cos, m22]]``, ``G = [b2 sin q1,
    b3 sin q2]``, and the knee's passive torque (Table 1's form; ``d`` all 0: none)."""

    m11: float
    m22: float
    a1: float
    b2: float
    b3: float
    phi0: float = 0.0
    d: tuple[float, float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    g: float = G

    @classmethod
    def from_anthropometry(
        cls, height_m: float = 1.75, mass_kg: float = 75.0, knee: KneeParams | None = None
    ) -> TwoLinkParams:
        """A double pendulum of Winter's (2009) thigh and leg-and-foot segments; ``knee``: its passive torque."""
        (ft, ct, rt, lt), (fs, cs, rs, ls) = WINTER_THIGH, WINTER_SHANK
        l1, l2 = lt * height_m, ls * height_m
        m1, m2 = ft * mass_kg, fs * mass_kg
        lc1, lc2 = ct * l1, cs * l2
        i1, i2 = m1 * (rt * l1) ** 2, m2 * (rs * l2) ** 2
        p = cls(i1 + m1 * lc1**2 + m2 * l1**2, i2 + m2 * lc2**2, m2 * l1 * lc2, (m1 * lc1 + m2 * l1) * G, m2 * lc2 * G)
        if knee is None:
            return p
        return cls(p.m11, p.m22, p.a1, p.b2, p.b3, knee.phi0, knee.d)

    def vector(self) -> Array:
        """The kernel's parameter vector ``[m11, m22, a1, b2, b3, g, phi0, d1..d6]``."""
        return np.array([self.m11, self.m22, self.a1, self.b2, self.b3, self.g, self.phi0, *self.d], dtype=np.float64)

    def model(self, x: Array, u: Array, jacobian: bool) -> tuple[Array, Array, Array, Array]:
        """As :meth:`KneeParams.model`, eqs. 4.23-4.25 (the EKF's Jacobian of ``f`` by central differences)."""
        s, cq = math.sin(x[0] - x[1]), math.cos(x[0] - x[1])
        det = self.m11 * self.m22 - (self.a1 * cq) ** 2
        w11, w12, w22 = self.m22 / det, -self.a1 * cq / det, self.m11 / det
        w21, a1, b2, b3 = w12, self.a1, self.b2, self.b3
        a = np.zeros((4, 4))
        a[0, 2] = a[1, 3] = 1.0
        a[2] = [-w11 * b2 * _sinc(x[0]), -w12 * b3 * _sinc(x[1]), w12 * a1 * x[2] * s, -w11 * a1 * x[3] * s]
        a[3] = [-w21 * b2 * _sinc(x[0]), -w22 * b3 * _sinc(x[1]), w22 * a1 * x[2] * s, -w21 * a1 * x[3] * s]
        c = np.zeros((4, 4))
        c[0, 2] = c[1, 3] = 1.0
        c[2, 0], c[3, 1] = -self.g * _sinc(x[0]), -self.g * _sinc(x[1])
        d, phi, phidot = self.d, x[0] - x[1], x[2] - x[3]
        tk = d[0] * (phi - self.phi0) + d[1] * phidot + d[2] * math.exp(d[3] * phi) - d[4] * math.exp(d[5] * phi)
        tau = np.array([u[0] - u[1] - tk, u[1] + tk])  # generalised forces of the joint torques
        bu = np.concatenate([np.zeros(2), np.array([[w11, w12], [w21, w22]]) @ tau])
        f, h = a @ x + bu, c @ x
        if not jacobian:
            return f, h, a, c
        jf = np.zeros((4, 4))
        jf[0, 2] = jf[1, 3] = 1.0
        for j in range(4):
            step = 1e-6 * max(1.0, abs(x[j]))
            e = np.zeros(4)
            e[j] = step
            hi, lo = self.model(x + e, u, False)[0], self.model(x - e, u, False)[0]
            jf[2:, j] = (hi[2:] - lo[2:]) / (2 * step)
        jh = np.zeros((4, 4))
        jh[0, 2] = jh[1, 3] = 1.0
        jh[2, 0], jh[3, 1] = -self.g * math.cos(x[0]), -self.g * math.cos(x[1])
        return f, h, jf, jh


def _sinc(x: float) -> float:
    return 1.0 - x * x / 6.0 if abs(x) < 1e-8 else math.sin(x) / x


Params = KneeParams | TwoLinkParams


class ContinuousFilter:
    """The SDRE estimator (``jacobian=False``, ``a=1``) or the EKF (``jacobian=True``, ``a=0``) of one model.

    Attributes:
        x: (n,) the estimate; ``P``: (n, n) the Riccati matrix.

    Args:
        params: the model (:class:`KneeParams`, n = 2; :class:`TwoLinkParams`, n = 4).
        q: (n,) diagonal of ``Q``; ``s``: (m,) diagonal of ``S`` (m = n here).
        a: the prescribed degree of stability (eq. 4.16; the thesis's 1 for the SDRE).
        max_step: the largest RK4 step (s); a sample interval is split into equal steps no longer.
        compiled: integrate with the numba kernel (False: the numpy reference, about 100x slower).
    """

    def __init__(
        self,
        params: Params,
        q: ArrayLike,
        s: ArrayLike,
        *,
        jacobian: bool = False,
        a: float | None = None,
        p0: ArrayLike | None = None,
        max_step: float = 1e-3,
        compiled: bool = True,
    ):
        self.params = params
        self.model_id = 1 if isinstance(params, KneeParams) else 2
        n = 2 if self.model_id == 1 else 4
        self.q = np.diag(np.asarray(q, dtype=np.float64) * np.ones(n))
        s_diag = np.asarray(s, dtype=np.float64) * np.ones(n)
        if not np.all(s_diag > 0):
            raise ValueError(f"S must be positive definite, got diag {s_diag}")
        self.sinv = 1.0 / s_diag
        self.jacobian = jacobian
        self.a = (0.0 if jacobian else 1.0) if a is None else float(a)
        self.p0 = np.eye(n) if p0 is None else np.asarray(p0, dtype=np.float64).copy()
        if not max_step > 0:
            raise ValueError(f"max_step must be positive, got {max_step}")
        self.max_step = max_step
        self.compiled = compiled
        self._p = params.vector()
        self.x = np.zeros(n)
        self.P = self.p0.copy()

    @property
    def n(self) -> int:
        return self.x.shape[0]

    def start(self, x0: ArrayLike) -> None:
        """Restart from ``x0`` with ``P = P0``."""
        self.x = np.asarray(x0, dtype=np.float64).copy()
        self.P = self.p0.copy()

    def derivative(self, x: Array, pm: Array, y: Array, u: Array) -> tuple[Array, Array]:
        """The joint right-hand side ``(xhat', P')`` in numpy (eqs. 4.14-4.16)."""
        f, h, am, cm = self.params.model(x, u, self.jacobian)
        k = pm @ cm.T * self.sinv
        return f + k @ (y - h), am @ pm + pm @ am.T + 2 * self.a * pm - k @ cm @ pm + self.q

    def integrate(self, y: ArrayLike, u: ArrayLike, dt: float) -> Array:
        """Advance by ``dt`` holding the measurement ``y`` and input ``u``; return the estimate."""
        yy, uu = np.asarray(y, dtype=np.float64), np.asarray(u, dtype=np.float64)
        if uu.ndim == 0:
            uu = uu.reshape(1)
        steps = max(1, math.ceil(dt / self.max_step - 1e-9))
        if self.compiled:
            kernel.integrate(
                self.model_id, self._p, self.a, self.jacobian, self.x, self.P, self.q, self.sinv, yy, uu, dt, steps
            )
            return self.x
        rate = kernel.stiffness(self.model_id, self._p, self.a, self.jacobian, self.x, self.P, self.sinv, uu)
        if rate * dt / steps > 0.5:
            steps = min(math.ceil(rate * dt / 0.5), 100000)
        h = dt / steps
        x, pm = self.x, self.P
        for _ in range(steps):
            k1 = self.derivative(x, pm, yy, uu)
            k2 = self.derivative(x + h / 2 * k1[0], pm + h / 2 * k1[1], yy, uu)
            k3 = self.derivative(x + h / 2 * k2[0], pm + h / 2 * k2[1], yy, uu)
            k4 = self.derivative(x + h * k3[0], pm + h * k3[1], yy, uu)
            x = x + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
            pm = pm + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
            pm = (pm + pm.T) / 2
        self.x, self.P = x, pm
        return self.x

    def run(self, ys: ArrayLike, us: ArrayLike, dt: float, x0: ArrayLike) -> Array:
        """Estimates ``(k, n)`` over a recording sampled every ``dt``: row 0 is ``x0``, row ``k`` integrates
        from sample ``k - 1`` to ``k`` holding sample ``k``."""
        yy = np.asarray(ys, dtype=np.float64)
        uu = np.asarray(us, dtype=np.float64).reshape(yy.shape[0], -1)
        self.start(x0)
        if self.compiled:
            steps = max(1, math.ceil(dt / self.max_step - 1e-9))
            out = kernel.run(
                self.model_id, self._p, self.a, self.jacobian, self.x, self.P, self.q, self.sinv, yy, uu, dt, steps
            )
            return np.asarray(out)
        out = np.empty((yy.shape[0], self.n))
        out[0] = self.x
        for k in range(1, yy.shape[0]):
            out[k] = self.integrate(yy[k], uu[k], dt)
        return out


def initial_angle(accel: ArrayLike, g: float = G) -> float:
    """A segment's angle from its resting accelerometer (thesis section 4.1.4): ``asin(-mean(y2) / g)`` for
    the thesis's ``y2 = -g sin x1`` (clipped to +/- 90 deg)."""
    m = float(np.mean(np.asarray(accel, dtype=np.float64)))
    return math.asin(min(1.0, max(-1.0, -m / g)))


def rotation_z(angle: ArrayLike) -> Array:
    """Rotations about z by ``angle`` (rad), ``(..., 3, 3)``."""
    a = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(a), np.sin(a)
    out = np.zeros((*a.shape, 3, 3))
    out[..., 0, 0], out[..., 0, 1], out[..., 1, 0], out[..., 1, 1] = c, -s, s, c
    out[..., 2, 2] = 1.0
    return out


def complementary_angle(
    gyro_dps: ArrayLike, accel_x: ArrayLike, accel_y: ArrayLike, dt: float, tau_s: float = 1.0
) -> Array:
    """A segment's sagittal angle (deg) from one IMU: gyro z integrated, pulled toward the accelerometer's
    tilt ``atan2(a_x, a_y)`` with time constant ``tau_s`` (axes of :mod:`gaitscope.sessions.synth.imu`: x anterior,
    y proximal; at rest ``a_x = g sin(angle)``, ``a_y = g cos(angle)``). Stands in for the YEI sensor's
    on-board orientation filter, whose settings the thesis says are unknown. Starts at the tilt."""
    w = np.asarray(gyro_dps, dtype=np.float64)
    tilt = np.degrees(np.arctan2(np.asarray(accel_x, dtype=np.float64), np.asarray(accel_y, dtype=np.float64)))
    k = dt / (tau_s + dt)
    out = np.empty_like(w)
    angle = float(tilt[0])
    out[0] = angle
    for i in range(1, w.shape[0]):
        angle = (1 - k) * (angle + w[i] * dt) + k * tilt[i]
        out[i] = angle
    return out


def rmx_knee_angle(r_thigh: ArrayLike, r_shank: ArrayLike) -> Array:
    """Knee flexion (deg) by the rotation-matrix method: the shank's frame in the thigh's,
    ``R = R_thigh^T R_shank``, read as a rotation about z; flexion is the thigh's angle less the shank's,
    ``-atan2(R[1, 0], R[0, 0])``. ``r_thigh``, ``r_shank``: ``(..., 3, 3)`` sensor-to-world rotations."""
    rt, rs = np.asarray(r_thigh, dtype=np.float64), np.asarray(r_shank, dtype=np.float64)
    rel = np.swapaxes(rt, -1, -2) @ rs
    return np.asarray(-np.degrees(np.arctan2(rel[..., 1, 0], rel[..., 0, 0])))

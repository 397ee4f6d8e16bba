"""Simulated FES-driven legs of seed 002 (Zhong 2016): the seated knee and the fixed-hip thigh and shank.

Both models are :mod:`gaitscope.estimators.sdre`'s; what this module adds is what the thesis's trials had and its
estimators do not know. Deterministic from a seed.

**Seated knee** (thesis section 4.1, :func:`seated_trial`): one leg of Table 1 (``J``, ``m``, ``l_c`` from
Winter 2009, :meth:`gaitscope.estimators.sdre.KneeParams.from_table1`) on a leg-extension machine, thigh horizontal
and still, 30 s per trial like the thesis's. The truth differs from the estimators' model as a real leg
differs from its identified model (choices, none tuned to the thesis's numbers):

- muscle activation follows the stimulation through a first-order lag with Table 1's ``Ta`` (the thesis's
  estimators take activation = stimulation, section 4.1.1);
- the FES torque's gain is off by a factor drawn once per trial, ``1 + 0.1 N(0, 1)`` (the thesis found
  the threshold current had moved between identification and experiment, section 4.1.4);
- stimulation: 3 s at rest, then trapezoid bursts (ramp 1.5 s, hold 2 s, ramp 1.5 s, off 2 s) whose
  hold level would, with the nominal model, hold the knee at an angle drawn uniformly from 15-45 deg
  (the thesis shows knee flexion-extension cycles, Fig. 12, without their timing);
- IMUs (both segments) sampled at 100 Hz (the thesis's rate) by :func:`gaitscope.sessions.synth.imu.imu_readings`
  with the MPU-9250's noise (the thesis's YEI sensor's is not given), a gyro bias about z of 0.1-1 deg/s
  (uniform, random sign; seed 002's simulation range), no other constant error, the shank sensor halfway
  down the shank so that it feels the motion's acceleration (the estimators take it for noise).

**Fixed-hip thigh and shank** (section 4.2, :func:`two_link_trial`): Winter's segments hanging from a
fixed hip (:meth:`gaitscope.estimators.sdre.TwoLinkParams.from_anthropometry`, the knee's passive torque of Table 1's
P1-L), swung through a gait-like hip and knee pattern (1.2 s cycles after 1 s at rest) by a computed-torque
controller on the true state (the thesis drives it with its synergy controller, chapter 5); the estimators
know the joint torques, as the thesis's know the controller's input. IMUs: a constant gyro bias on both
segments (``gyro_bias_dps``, the thesis's "level"), accelerometer noise, and by default gravity only
(the thesis: "only gravitational acceleration is considered").
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from gaitscope.estimators._sdre_kernel import two_link_rhs
from gaitscope.estimators.sdre import WINTER_SHANK, WINTER_THIGH, KneeParams, TwoLinkParams
from gaitscope.sessions.synth.imu import ImuErrors, ImuSpec, imu_readings

__all__ = [
    "IMU_RATE_HZ",
    "LEGS",
    "TRUTH_RATE_HZ",
    "FesTrial",
    "rest_angle",
    "seated_trial",
    "stimulation",
    "two_link_trial",
]

#: The thesis's IMU rate and its encoder's (the estimators integrate at the latter).
IMU_RATE_HZ: Final = 100.0
TRUTH_RATE_HZ: Final = 1000.0
#: Table 1's legs, in Table 2's order.
LEGS: Final = ("P1-L", "P1-R", "P2-L", "P2-R", "P3-L", "P3-R")


@dataclass(frozen=True)
class FesTrial:
    """One simulated trial.

    Attributes:
        t: (n,) truth and input times (s) at :data:`TRUTH_RATE_HZ`; ``t_imu``: (k,) IMU times.
        angles: (n, j) true absolute segment angles from the vertical, forward positive (rad): the shank
            (seated); thigh and shank (two-link).
        rates: (n, j) their rates (rad/s).
        knee_deg: (n,) true knee flexion (deg); ``hip_deg``: (n,) thigh from the vertical (two-link, else NaN).
        u: (n, i) the input the estimators know: stimulation (seated) or hip and knee torques (N m).
        gyro: (k, s, 3) deg/s, ``accel``: (k, s, 3) m/s^2: the IMUs (sensor 0 thigh, 1 shank), axes of
            :mod:`gaitscope.sessions.synth.imu` (x anterior, y proximal, z right).
        params: the estimators' model (:class:`KneeParams` or :class:`TwoLinkParams`).
        gyro_bias_dps: (s,) the bias about z of each sensor.
    """

    t: np.ndarray
    angles: np.ndarray
    rates: np.ndarray
    knee_deg: np.ndarray
    hip_deg: np.ndarray
    u: np.ndarray
    t_imu: np.ndarray
    gyro: np.ndarray
    accel: np.ndarray
    params: KneeParams | TwoLinkParams
    gyro_bias_dps: np.ndarray


def rest_angle(p: KneeParams) -> float:
    """The shank's resting angle ``x1`` (rad) with no stimulation: gravity against the passive torque."""
    return float(
        brentq(lambda x: -p.beta * math.sin(x) + p.alpha * float(p.torques(math.pi / 2 - x, 0.0, 0.0)), -1.4, 1.5)
    )


def stimulation(t: np.ndarray, levels: np.ndarray, rest_s: float = 3.0) -> np.ndarray:
    """Trapezoid bursts after ``rest_s``: ramp 1.5 s, hold 2 s, ramp 1.5 s, off 2 s; burst ``i`` holds
    ``levels[i]`` (the last one repeats)."""
    period, ramp, hold = 7.0, 1.5, 2.0
    tau = t - rest_s
    k = np.clip(np.floor(tau / period).astype(int), 0, len(levels) - 1)
    s = tau - np.floor(tau / period) * period
    shape = np.clip(np.minimum(s / ramp, (2 * ramp + hold - s) / ramp), 0.0, 1.0)
    return np.where(tau >= 0, shape * levels[k], 0.0)


def _hold_level(p: KneeParams, knee_rad: float) -> float:
    """The stimulation that holds the nominal leg still at ``knee_rad`` (0..1, clipped)."""
    x1 = math.pi / 2 - knee_rad
    need = p.beta * math.sin(x1) / p.alpha - float(p.torques(knee_rad, 0.0, 0.0))
    gain = float(p.torques(knee_rad, 0.0, 1.0) - p.torques(knee_rad, 0.0, 0.0))
    return float(np.clip(need / gain, 0.0, 1.0)) if gain > 0 else 0.0


def _imu(
    angle: np.ndarray, rate: np.ndarray, acc: np.ndarray, bias_dps: float, spec: ImuSpec, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """One sensor's readings (angle, rate in rad, rad/s; world acceleration (k, 2) forward and up)."""
    errors = ImuErrors(np.eye(3), np.array([0.0, 0.0, bias_dps]), np.zeros(3), np.zeros(3), np.zeros(3))
    world = np.column_stack([acc, np.zeros(len(angle))])
    return imu_readings(np.degrees(angle), np.degrees(rate), world, IMU_RATE_HZ, spec, errors, rng)


def _point_acc(r: float, a: np.ndarray, w: np.ndarray, dw: np.ndarray) -> np.ndarray:
    """World acceleration (forward, up) of a point ``r`` down a segment at angle ``a`` (distal end forward)
    turning about a fixed proximal joint."""
    return r * np.column_stack([np.cos(a) * dw - np.sin(a) * w**2, np.sin(a) * dw + np.cos(a) * w**2])


def _bias(rng: np.random.Generator) -> float:
    return float(rng.uniform(0.1, 1.0) * rng.choice([-1.0, 1.0]))


def seated_trial(
    leg: str, seed: int, duration_s: float = 30.0, gain_error_sd: float = 0.1, spec: ImuSpec | None = None
) -> FesTrial:
    """One 30 s leg-extension trial of Table 1's ``leg`` (module docstring)."""
    rng = np.random.default_rng(seed)
    p = KneeParams.from_table1(leg)
    gain = 1.0 + gain_error_sd * float(rng.standard_normal())
    levels = np.array([_hold_level(p, math.radians(k)) for k in rng.uniform(15.0, 45.0, 5)])
    t = np.arange(round(duration_s * TRUTH_RATE_HZ) + 1) / TRUTH_RATE_HZ
    ta = max(p.activation_s, 1e-3)

    def rhs(time: float, s: np.ndarray) -> list[float]:
        x1, x2, act = s
        u = float(stimulation(np.array([time]), levels)[0])
        phi, phidot = math.pi / 2 - x1, -x2
        tp = float(p.torques(phi, phidot, 0.0))
        tke = float(p.torques(phi, phidot, 1.0)) - tp
        return [x2, -p.beta * math.sin(x1) + p.alpha * (tp + gain * tke * act), (u - act) / ta]

    sol = solve_ivp(rhs, (0.0, t[-1]), [rest_angle(p), 0.0, 0.0], t_eval=t, rtol=1e-8, atol=1e-10, max_step=0.01)
    x1, x2 = sol.y[0], sol.y[1]
    dw = np.gradient(x2, t)
    spec = spec or ImuSpec()
    every = round(TRUTH_RATE_HZ / IMU_RATE_HZ)
    i = np.arange(0, len(t), every)
    zeros = np.zeros(len(i))
    biases = np.array([_bias(rng), _bias(rng)])
    seg = p.com / WINTER_SHANK[1]  # the shank's length back from l_c
    thigh = _imu(np.full(len(i), math.pi / 2), zeros, np.zeros((len(i), 2)), biases[0], spec, rng)
    shank = _imu(x1[i], x2[i], _point_acc(seg / 2, x1[i], x2[i], dw[i]), biases[1], spec, rng)
    return FesTrial(
        t=t,
        angles=x1[:, None],
        rates=x2[:, None],
        knee_deg=np.degrees(math.pi / 2 - x1),
        hip_deg=np.full(len(t), np.nan),
        u=stimulation(t, levels)[:, None],
        t_imu=t[i],
        gyro=np.stack([thigh[0], shank[0]], axis=1),
        accel=np.stack([thigh[1], shank[1]], axis=1),
        params=p,
        gyro_bias_dps=biases,
    )


def _desired(t: np.ndarray, period_s: float, rest_s: float) -> np.ndarray:
    """Gait-like hip (thigh) and knee targets (rad): a 1 s smooth start after ``rest_s``."""
    s = np.clip(t - rest_s, 0.0, 1.0)
    ramp = 6 * s**5 - 15 * s**4 + 10 * s**3
    w = 2 * math.pi * np.maximum(t - rest_s, 0.0) / period_s
    hip = 0.05 + ramp * 0.3 * np.sin(w)
    knee = 0.08 + ramp * 0.9 * ((1 - np.cos(w - 1.0)) / 2) ** 2
    return np.column_stack([hip, hip - knee])  # thigh and shank angles


def two_link_trial(
    seed: int,
    gyro_bias_dps: float,
    duration_s: float = 11.0,
    period_s: float = 1.2,
    rest_s: float = 1.0,
    motion_acceleration: bool = False,
    spec: ImuSpec | None = None,
) -> FesTrial:
    """The fixed-hip leg swung through ``duration_s`` of gait-like cycles (module docstring); both gyros
    read ``gyro_bias_dps`` too (the sign drawn per sensor)."""
    rng = np.random.default_rng(seed)
    p = TwoLinkParams.from_anthropometry(knee=KneeParams.from_table1("P1-L"))
    vec = p.vector()
    h = 1.0 / TRUTH_RATE_HZ
    t = np.arange(round(duration_s * TRUTH_RATE_HZ) + 1) * h
    qd = _desired(t, period_s, rest_s)
    dqd = np.gradient(qd, t, axis=0)
    ddqd = np.gradient(dqd, t, axis=0)
    x = np.array([qd[0, 0], qd[0, 1], 0.0, 0.0])
    xs, us = np.empty((len(t), 4)), np.empty((len(t), 2))
    kp, kd = 400.0, 40.0
    for k in range(len(t)):
        xs[k] = x
        u = _computed_torque(p, x, ddqd[k] + kp * (qd[k] - x[:2]) + kd * (dqd[k] - x[2:]))
        us[k] = u

        def f(s: np.ndarray, u: np.ndarray = u) -> np.ndarray:
            acc = two_link_rhs(vec, s, u)
            return np.array([s[2], s[3], acc[0], acc[1]])

        k1 = f(x)
        k2 = f(x + h / 2 * k1)
        k3 = f(x + h / 2 * k2)
        k4 = f(x + h * k3)
        x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    dw = np.gradient(xs[:, 2:], t, axis=0)
    spec = spec or ImuSpec()
    i = np.arange(0, len(t), round(TRUTH_RATE_HZ / IMU_RATE_HZ))
    signs = rng.choice([-1.0, 1.0], 2)
    thigh_len, shank_len = WINTER_THIGH[3] * 1.75, WINTER_SHANK[3] * 1.75  # from_anthropometry's subject
    if motion_acceleration:
        a_thigh = _point_acc(thigh_len / 2, xs[i, 0], xs[i, 2], dw[i, 0])
        knee_acc = _point_acc(thigh_len, xs[i, 0], xs[i, 2], dw[i, 0])
        a_shank = knee_acc + _point_acc(shank_len / 2, xs[i, 1], xs[i, 3], dw[i, 1])
    else:
        a_thigh = a_shank = np.zeros((len(i), 2))
    biases = gyro_bias_dps * signs
    thigh = _imu(xs[i, 0], xs[i, 2], a_thigh, biases[0], spec, rng)
    shank = _imu(xs[i, 1], xs[i, 3], a_shank, biases[1], spec, rng)
    return FesTrial(
        t=t,
        angles=xs[:, :2],
        rates=xs[:, 2:],
        knee_deg=np.degrees(xs[:, 0] - xs[:, 1]),
        hip_deg=np.degrees(xs[:, 0]),
        u=us,
        t_imu=t[i],
        gyro=np.stack([thigh[0], shank[0]], axis=1),
        accel=np.stack([thigh[1], shank[1]], axis=1),
        params=p,
        gyro_bias_dps=biases,
    )


def _computed_torque(p: TwoLinkParams, x: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """Hip and knee joint torques (N m) that give the accelerations ``qdd`` at state ``x`` (inverse dynamics
    of eq. 4.18 with the knee's passive torque)."""
    s, c = math.sin(x[0] - x[1]), math.cos(x[0] - x[1])
    m = np.array([[p.m11, p.a1 * c], [p.a1 * c, p.m22]])
    forces = m @ qdd + np.array(
        [p.a1 * x[3] ** 2 * s + p.b2 * math.sin(x[0]), -p.a1 * x[2] ** 2 * s + p.b3 * math.sin(x[1])]
    )
    d, phi, phidot = p.d, x[0] - x[1], x[2] - x[3]
    tk = d[0] * (phi - p.phi0) + d[1] * phidot + d[2] * math.exp(d[3] * phi) - d[4] * math.exp(d[5] * phi)
    knee = forces[1] - tk  # generalised forces [hip - knee - tk, knee + tk]
    return np.array([forces[0] + knee + tk, knee])

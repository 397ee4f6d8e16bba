"""Seed 002's SDRE estimator as a stack estimator: knee and thigh angles live from thigh and shank IMUs.

:class:`SDREKnee` (``sdre_knee``) runs the fixed-hip two-link SDRE of :mod:`gaitscope.estimators.sdre` (Zhong 2016
section 4.2) on the sagittal channels of a thigh and a shank IMU (axes of ``gaitscope.sessions.schema.CHANNELS``:
x anterior, y along the segment toward proximal, z to the right; a segment's angle is from the vertical,
positive with its distal end forward, so at rest ``accel_x = g sin(angle)``): ``y = [gyro_z(thigh),
gyro_z(shank), -accel_x(thigh), -accel_x(shank)]`` in rad/s and m/s^2, the thesis's ``-g sin x``.

What the model means for a walking leg: the thesis's model is a leg hanging from a hip that does not
move, driven by known FES and motor torques. A walking leg has no FES (``u = 0``) and its hip moves; in
stance the leg is an inverted pendulum over the foot, not a pendulum under the hip. The model is
therefore wrong for most of the stride and the filter leans on its measurements: the process noise
``q_rate`` is large (the model's accelerations are trusted little), and the accelerometer's ``s_accel``
is large too, because while walking it reads the segment's own acceleration (several m/s^2) on top of
gravity, which the thesis's measurement model (gravity only, "slow motion") leaves out. What remains of
the thesis is the structure: gyro rates integrated, corrected toward the accelerometer's tilt with a
state-dependent gain. Its error on the virtual cohort, against a complementary-filter baseline, is in
``gaitscope crossval --study sdre`` (``docs/results.md``).

Defaults (choices): the segments of a subject of height ``leg_length / 0.530`` (Winter 2009) and 75 kg
(the mass changes ``M``, ``V`` and ``G`` by one factor and so not the estimate), no passive torque, RK4
steps of at most 1 ms (the thesis's rate), ``P0 = I``, ``a = 1``; ``q_angle`` 1e-4 rad^2/s, ``s_gyro``
1e-3 (rad/s)^2 s, ``s_accel`` 4 (m/s^2)^2 s (a segment's acceleration in walking, about 2 m/s^2 rms) and
``q_rate`` 1000 (rad/s^2)^2 s, the best of ``s_accel`` 0.1-40 x ``q_rate`` 10-1000 on cohort subject 0,
who is left out of the study's walking evaluation. Outputs hold their last value on an input that
is missing or not finite, and after the state diverges (the filter restarts on the next good sample).
"""

from __future__ import annotations

import math
from typing import Final

import numpy as np
from numpy.typing import NDArray

from gaitscope.estimators._sdre_kernel import healthy
from gaitscope.estimators.descriptor import Descriptor, Tunable, out
from gaitscope.estimators.protocol import check_params, elapsed
from gaitscope.estimators.sdre import ContinuousFilter, G, TwoLinkParams

__all__ = ["DESCRIPTOR", "SDREKnee"]

Array = NDArray[np.float64]

_HIP_FRACTION = 0.530  # Winter (2009): hip height over body height
_DEFAULTS = {"q_angle": 1e-4, "q_rate": 1000.0, "s_gyro": 1e-3, "s_accel": 4.0}
_DIVERGED_RAD = 10.0  # a segment angle past this (or anything not finite) has diverged
_NO_TORQUE = np.zeros(2)  # u: a walking leg has no FES and the joint torques are not measured (read only)


class SDREKnee:
    """The two-link SDRE on a thigh and a shank IMU (module docstring): knee flexion and thigh angle (deg)."""

    name = "sdre_knee"
    inputs: tuple[str, ...] = (
        "imu_thigh_gyro_z_dps",
        "imu_thigh_accel_x_m_s2",
        "imu_shank_gyro_z_dps",
        "imu_shank_accel_x_m_s2",
    )
    optional_inputs: tuple[str, ...] = ()
    outputs: tuple[tuple[str, str], ...] = (("knee_sdre_deg", "deg"), ("thigh_sdre_deg", "deg"))
    tunables: tuple[str, ...] = tuple(_DEFAULTS)

    def __init__(self, leg_length: float, mass_kg: float = 75.0, max_step: float = 1e-3, **tuning: float):
        if not (math.isfinite(leg_length) and 0.3 <= leg_length <= 1.5):
            raise ValueError(f"leg length must be 0.3..1.5 m, got {leg_length}")
        self.params = TwoLinkParams.from_anthropometry(leg_length / _HIP_FRACTION, mass_kg)
        self.max_step = max_step
        self.tuning = dict(_DEFAULTS)
        self.retune(**tuning)
        self.reset()

    def _build(self) -> None:
        t = self.tuning
        q = [t["q_angle"], t["q_angle"], t["q_rate"], t["q_rate"]]
        s = [t["s_gyro"], t["s_gyro"], t["s_accel"], t["s_accel"]]
        self.filter = ContinuousFilter(self.params, q, s, max_step=self.max_step)

    def reset(self) -> None:
        self._build()
        self._last: float | None = None
        self._out = [0.0, 0.0]

    def retune(self, **params: float) -> None:
        check_params(self, params)
        for k, v in params.items():
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"{k} must be positive and finite, got {v}")
        self.tuning.update(params)
        if params and getattr(self, "filter", None) is not None:
            x, pm = self.filter.x.copy(), self.filter.P.copy()
            self._build()
            self.filter.x, self.filter.P = x, pm

    @property
    def state(self) -> Array:
        return self.filter.x

    @property
    def covariance(self) -> Array:
        return self.filter.P

    def step(self, t: float, z: Array) -> Array:
        """One sample: integrate the SDRE from the last good sample to ``t`` holding this one.

        Written for its cost (issue #24: the Python around the kernel was a third of the sample): Python
        floats, one compiled call for the divergence check (:func:`gaitscope.estimators._sdre_kernel.healthy`)."""
        w_th, a_th, w_sh, a_sh = z[:4].tolist()  # Python numbers (floats from the float64 the stack sends)
        if not (math.isfinite(w_th) and math.isfinite(a_th) and math.isfinite(w_sh) and math.isfinite(a_sh)):
            return np.array(self._out)
        dt, restart = elapsed(self._last, t)
        y = np.array([math.radians(w_th), math.radians(w_sh), -a_th, -a_sh])
        if self._last is None or restart:
            self.filter.start([_tilt(a_th), _tilt(a_sh), y[0], y[1]])
        elif dt > 0:
            x = self.filter.integrate(y, _NO_TORQUE, dt)
            if not healthy(x, self.filter.P, _DIVERGED_RAD):
                self._last = None  # diverged: start again from the next good sample, hold the output
                return np.array(self._out)
        self._last = t
        x0, x1 = self.filter.x[:2].tolist()
        self._out = [math.degrees(math.remainder(x0 - x1, 2 * math.pi)), math.degrees(math.remainder(x0, 2 * math.pi))]
        return np.array(self._out)


def _tilt(accel_x: float) -> float:
    """A segment's angle (rad) from a resting accelerometer's x (``g sin(angle)``)."""
    return math.asin(max(-1.0, min(1.0, accel_x / G)))


#: The SDRE knee as a session and the views know it (:mod:`gaitscope.estimators.descriptor`): run only when named.
DESCRIPTOR: Final = Descriptor(
    name=SDREKnee.name,
    label="SDRE knee angle from IMUs (seed 002)",
    inputs=SDREKnee.inputs,
    optional_inputs=SDREKnee.optional_inputs,
    outputs=(
        out("knee_sdre_deg", "deg", "knee flexion from the thigh and shank IMUs, (+) flexion"),
        out("thigh_sdre_deg", "deg", "thigh angle from vertical from the IMUs"),
    ),
    quantities={"knee_sdre_deg": "knee_angle"},
    tunables=tuple(Tunable(name) for name in SDREKnee.tunables),
    opt_in=True,
    purpose="Knee angle from thigh and shank IMUs. Meant for seated, FES-driven legs: in walking its knee is about "
    "12 deg off (docs/results.md).",
    paper="Zhong 2016, MS thesis (seed 002)",
)

"""The centre of mass relative to the stance foot, from leg kinematics (seed 001 Sec. III).

Seed 001 measured no centre of mass: the Ekso's hip and knee angles, with the user's thigh and shank
lengths and Winter's anthropometry, gave the pelvis's position relative to the stance foot, and the
centre of mass was taken at the pelvis's centroid; velocities by finite differences. gaitscope does the
same from the sagittal segment angles a device reports (thigh and shank of both legs, angle from the
vertical, positive with the distal end forward) and their angular velocities:

- stance leg: the one whose foot carries the larger vertical force (at mid-stance, where the filter
  reads the estimate, one foot carries nearly all of it);
- position: the hip joint centre relative to the stance leg's ankle, raised by the ankle height
  (``x = -(l_t sin th + l_s sin sh)``, ``z = l_t cos th + l_s cos sh + h_a``); the pelvis stands in for
  the centre of mass (seed 001's choice);
- velocity: the time derivative of that position from the angular velocities (exact for a foot that
  does not move), rather than a finite difference of the position;
- lateral position and velocity are not observable from sagittal angles: NaN (the filter skips them);
- segment lengths, when not given, from the leg length with Winter's (2009) fractions of height: thigh
  0.245, shank 0.246, ankle height 0.039, hip height 0.530.

As a stack estimator (:class:`KinematicCoM`, ``com_kin``) it derives the sagittal centre-of-mass channels
for a device that does not send them, so the intent filter runs on leg kinematics (a channel the device
sends wins over the derived one). Its error on the virtual cohort (sensor offsets, the heel rather than
the ankle under the body, the hip below the true centre of mass) is measured by ``gaitscope crossval
--study intent`` (``docs/results.md``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from gaitscope.estimators.descriptor import Descriptor, out
from gaitscope.estimators.protocol import check_params

__all__ = ["DESCRIPTOR", "KinematicCoM", "LegGeometry", "com_from_legs"]

Array = NDArray[np.float64]

#: Winter (2009) segment lengths as fractions of height; the leg length is the hip height.
_HIP, _THIGH, _SHANK, _ANKLE = 0.530, 0.245, 0.246, 0.039


@dataclass(frozen=True)
class LegGeometry:
    """Thigh and shank lengths and the ankle's height above the sole (m)."""

    thigh_m: float
    shank_m: float
    ankle_height_m: float

    @classmethod
    def from_leg_length(cls, leg_length_m: float) -> LegGeometry:
        """Winter's fractions of height, with height = leg length / 0.530."""
        if not (math.isfinite(leg_length_m) and 0.3 <= leg_length_m <= 1.5):
            raise ValueError(f"leg length must be 0.3..1.5 m, got {leg_length_m}")
        height = leg_length_m / _HIP
        return cls(_THIGH * height, _SHANK * height, _ANKLE * height)


#: Order of :func:`com_from_legs`' outputs: the intent filter's centre-of-mass channels.
OUTPUTS: Final = ("forward_m", "lateral_m", "up_m", "forward_vel_m_s", "lateral_vel_m_s", "up_vel_m_s")


def com_from_legs(
    geometry: LegGeometry,
    thigh_deg: ArrayLike,
    shank_deg: ArrayLike,
    thigh_dps: ArrayLike,
    shank_dps: ArrayLike,
    force_n: ArrayLike,
    thigh_contra_deg: ArrayLike,
    shank_contra_deg: ArrayLike,
    thigh_contra_dps: ArrayLike,
    shank_contra_dps: ArrayLike,
    force_contra_n: ArrayLike,
) -> Array:
    """Centre of mass relative to the stance foot, ``(n, 6)`` in :data:`OUTPUTS` order (m, m/s).

    Every argument is an array of the same length (or a scalar); a sample where a needed angle, rate or
    either force is not finite gives NaN in the entries that need it.
    """
    th, sh = np.radians(thigh_deg), np.radians(shank_deg)
    thc, shc = np.radians(thigh_contra_deg), np.radians(shank_contra_deg)
    force, force_c = np.asarray(force_n, dtype=np.float64), np.asarray(force_contra_n, dtype=np.float64)
    contra = force_c > force
    known = np.isfinite(force) & np.isfinite(force_c)
    t = np.where(contra, thc, th)
    s = np.where(contra, shc, sh)
    wt = np.radians(np.where(contra, thigh_contra_dps, thigh_dps))
    ws = np.radians(np.where(contra, shank_contra_dps, shank_dps))
    g = geometry
    x = -(g.thigh_m * np.sin(t) + g.shank_m * np.sin(s))
    z = g.thigh_m * np.cos(t) + g.shank_m * np.cos(s) + g.ankle_height_m
    vx = -(g.thigh_m * np.cos(t) * wt + g.shank_m * np.cos(s) * ws)
    vz = -(g.thigh_m * np.sin(t) * wt + g.shank_m * np.sin(s) * ws)
    nan = np.full(np.broadcast(x, known).shape, np.nan)
    out = np.stack([x, nan, z, vx, nan, vz], axis=-1)
    out[~np.broadcast_to(known, nan.shape)] = np.nan
    return out


#: Largest plausible magnitudes of the estimate: position (m) and velocity (m/s) of the pelvis over the foot.
_MAX_POSITION_M, _MAX_VELOCITY_M_S = 3.0, 10.0


class KinematicCoM:
    """:func:`com_from_legs` sample by sample, a stack estimator (``com_kin``) deriving the sagittal
    centre-of-mass channels (forward and up position and velocity relative to the stance foot).

    Its outputs must stay finite (a stack counts a non-finite output as a failure): while an input is
    missing or the estimate implausible (beyond 3 m or 10 m/s), the last estimate holds; before the
    first one they are 0. The intent filter, which reads them at mid-stance, holds and flags its own
    estimate when the leg channels it watches drop out.
    """

    name = "com_kin"
    inputs: tuple[str, ...] = (
        "thigh_angle_deg",
        "thigh_vel_dps",
        "shank_angle_deg",
        "shank_vel_dps",
        "thigh_angle_contra_deg",
        "thigh_vel_contra_dps",
        "shank_angle_contra_deg",
        "shank_vel_contra_dps",
        "foot_force_N",
        "foot_force_contra_N",
    )
    optional_inputs: tuple[str, ...] = ()
    outputs: tuple[tuple[str, str], ...] = (
        ("com_forward_m", "m"),
        ("com_up_m", "m"),
        ("com_forward_vel_m_s", "m/s"),
        ("com_up_vel_m_s", "m/s"),
    )
    tunables: tuple[str, ...] = ()
    state = None
    covariance = None

    def __init__(self, leg_length: float):
        self.geometry = LegGeometry.from_leg_length(leg_length)
        self.reset()

    def reset(self) -> None:
        self._out = [0.0, 0.0, 0.0, 0.0]

    def retune(self, **params: float) -> None:
        check_params(self, params)

    def step(self, t: float, z: Array) -> Array:
        """One sample (plain float arithmetic: about a microsecond)."""
        th, wth, sh, wsh, thc, wthc, shc, wshc, f, fc = z.tolist()
        if fc > f:  # the other foot carries the load (NaN compares False: checked below)
            th, wth, sh, wsh = thc, wthc, shc, wshc
        g = self.geometry
        a, b = math.radians(th), math.radians(sh)
        wa, wb = math.radians(wth), math.radians(wsh)
        try:
            sa, ca, sb, cb = math.sin(a), math.cos(a), math.sin(b), math.cos(b)
        except ValueError:  # an infinite angle
            return np.array(self._out)
        x = -(g.thigh_m * sa + g.shank_m * sb)
        up = g.thigh_m * ca + g.shank_m * cb + g.ankle_height_m
        vx = -(g.thigh_m * ca * wa + g.shank_m * cb * wb)
        vz = -(g.thigh_m * sa * wa + g.shank_m * sb * wb)
        if (
            f == f
            and fc == fc
            and abs(x) < _MAX_POSITION_M
            and abs(up) < _MAX_POSITION_M
            and abs(vx) < _MAX_VELOCITY_M_S
            and abs(vz) < _MAX_VELOCITY_M_S
        ):  # NaN and inf fail every comparison
            self._out = [x, up, vx, vz]
        return np.array(self._out)


#: The kinematic centre of mass as a session and the views know it (:mod:`gaitscope.estimators.descriptor`):
#: a front end deriving the centre-of-mass channels a source may not send.
DESCRIPTOR: Final = Descriptor(
    name=KinematicCoM.name,
    label="Centre of mass from leg kinematics (seed 001)",
    inputs=KinematicCoM.inputs,
    optional_inputs=KinematicCoM.optional_inputs,
    outputs=tuple(out(name, unit) for name, unit in KinematicCoM.outputs),
    derives=True,
    purpose="The centre of mass over the stance foot from both legs' thigh and shank angles, for the intent estimator.",
    paper="Karulkar and Wensing 2021 (seed 001)",
)

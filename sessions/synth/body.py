"""Whole-body quantities of a generated walk: the other leg, the feet's loads, the centre of mass relative
to the stance foot, and where each IMU is and how it accelerates.

:func:`body_columns` takes the kinematics :mod:`gaitscope.sessions.synth.cohort` has built for one walk (per stride
and sample, shape ``(n_strides, samples_per_stride)``) and returns the extra clean columns of schema
version 2 of the sensor frame (column names in :mod:`gaitscope.sessions.schema`). It draws no random numbers: every
per-subject number comes from :class:`~gaitscope.sessions.synth.cohort.SubjectParams`, so the existing signals'
random streams are untouched. Sources and modelling choices are in ``docs/cohort.md`` ("Schema version 2").

Frame: the walker's (a treadmill's lab frame, inertial), x forward, z up, origin at the hip's mean
position; the ground line under the walker has the slope of the incline and the belt moves along it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Final

import numpy as np

from gaitscope.sessions import schema as s

__all__ = [
    "COM_HEIGHT_FRAC",
    "PELVIS_IMU_M",
    "SHANK_IMU_FRAC",
    "STEP_WIDTH_M",
    "THIGH_IMU_FRAC",
    "Kinematics",
    "body_columns",
    "second_derivative",
    "smooth_step",
]

G: Final = 9.81
#: Whole-body centre of mass above the floor in standing, as a fraction of height (choice: the round
#: figure of about 55 % usually quoted for adults; hip joint centres are at Winter's 0.530).
COM_HEIGHT_FRAC: Final = 0.55
#: Distance between the feet's lines of progression (choice).
STEP_WIDTH_M: Final = 0.10
#: Where each IMU sits (choices). Pelvis: on the sacrum, 0.10 m behind and 0.08 m above the hip joint
#: centres (pelvis frame: x anterior, y up). Thigh: mid-thigh. Shank: above the ankle, 80 % of the shank
#: from the knee (seed 000's ExoBoot IMU). Foot: on the back of the heel (seed 000's foot IMU), half an
#: ankle height above the sole. Fractions are of the segment's length from its proximal joint.
PELVIS_IMU_M: Final = (-0.10, 0.08)
THIGH_IMU_FRAC: Final = 0.5
SHANK_IMU_FRAC: Final = 0.8
DUPLICATE_TOL_S: Final = 1e-9


@dataclass(frozen=True)
class Kinematics:
    """One walk's kinematics as the cohort built them; arrays ``(n, N)`` unless said, angles in deg.

    Attributes:
        t: time (s); the last sample of a stride and the first of the next are the same instant.
        p: (N,) phase of each sample in its stride, 0..1.
        q, qc: warped source phases of the ipsilateral and contralateral curves.
        foot_off, contra: (n,) stance fraction (against ``q``) and contralateral heel strike (phase).
        period, speed, incline: (n,) stride duration (s), belt speed (m/s), incline (deg).
        thigh, shank, foot: true (offset-free) ipsilateral segment angles.
        thigh_c, shank_c, foot_c: true contralateral segment angles (with the subject's asymmetry).
        pelvis: pelvic anterior tilt.
        hip_x, hip_z: hip joint centre (m).
        heel_x, heel_z: ipsilateral heel (m), the ``HEEL_*`` columns.
        com_x, com_y, com_z: centre-of-mass oscillation about the walker (m), ``COM_POSITION``.
        z_amp: peak-to-peak vertical centre-of-mass excursion (m).
        thigh_length, shank_length, heel_back, ankle_height, height, mass: the subject's (m, kg).
    """

    t: np.ndarray
    p: np.ndarray
    q: np.ndarray
    qc: np.ndarray
    foot_off: np.ndarray
    contra: np.ndarray
    period: np.ndarray
    speed: np.ndarray
    incline: np.ndarray
    thigh: np.ndarray
    shank: np.ndarray
    foot: np.ndarray
    thigh_c: np.ndarray
    shank_c: np.ndarray
    foot_c: np.ndarray
    pelvis: np.ndarray
    hip_x: np.ndarray
    hip_z: np.ndarray
    heel_x: np.ndarray
    heel_z: np.ndarray
    com_x: np.ndarray
    com_y: np.ndarray
    com_z: np.ndarray
    z_amp: np.ndarray
    thigh_length: float
    shank_length: float
    heel_back: float
    ankle_height: float
    height: float
    mass: float


def body_columns(k: Kinematics) -> dict[str, np.ndarray]:
    """The clean columns schema version 2 adds to a walk, each ``(n, N)``.

    Vertical ground reaction force of each foot, centre of mass relative to the stance foot, the linear
    acceleration of each IMU's mounting point and the contralateral step length (the segment and joint
    angles of the other leg and the pelvis are assembled by the cohort itself).
    """
    cols: dict[str, np.ndarray] = {}
    share, i_hc = _ipsi_load_share(k)
    total = k.mass * (G + _com_vertical_acceleration(k))
    cols[s.VERTICAL_GRF] = share * total
    cols[s.VERTICAL_GRF_CONTRA] = (1.0 - share) * total
    cols.update(zip(s.COM_STANCE_POSITION, _com_from_stance_foot(k, i_hc), strict=True))
    points = _imu_points(k)
    accelerations = second_derivative(k.t, np.stack([xz for seg in s.IMU_SEGMENTS for xz in points[seg]]))
    names = [name for seg in s.IMU_SEGMENTS for name in s.IMU_POINT_ACCELERATION[seg]]
    cols.update(zip(names, accelerations, strict=True))
    stride = k.speed * k.period
    cols[s.STEP_LENGTH_CONTRA] = np.repeat((stride * k.contra)[:, None], k.p.size, axis=1)
    return cols


def second_derivative(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """d2x/dt2 of samples on a grid whose stride boundaries appear twice (same time), same shape.

    ``t`` is ``(n, N)``; ``x`` is ``(n, N)`` or a stack of such, ``(..., n, N)``. Three-point second
    differences on the distinct instants (exact for a quadratic, on an uneven grid too), the end values
    repeated at the ends; both copies of a repeated instant get its value.
    """
    tf = t.reshape(-1)
    xf = x.reshape(*x.shape[:-2], tf.size)
    keep = np.r_[np.diff(tf) > DUPLICATE_TOL_S, True]  # the later copy of a repeated instant
    out = np.zeros_like(xf)
    if keep.sum() > 2:
        h = np.diff(tf[keep])
        slope = np.diff(xf[..., keep], axis=-1) / h
        inner = 2.0 * np.diff(slope, axis=-1) / (h[1:] + h[:-1])
        out[..., keep] = np.concatenate([inner[..., :1], inner, inner[..., -1:]], axis=-1)
    dropped = np.flatnonzero(~keep)
    out[..., dropped] = out[..., dropped + 1]
    return out.reshape(x.shape)


# --- private helpers -----------------------------------------------------------------------------


def smooth_step(u: np.ndarray) -> np.ndarray:
    """0 -> 1 over u in [0, 1] with zero slope at both ends."""
    return 0.5 * (1.0 - np.cos(np.pi * np.clip(u, 0.0, 1.0)))


def _ipsi_load_share(k: Kinematics) -> tuple[np.ndarray, np.ndarray]:
    """Share of the body's vertical load on the ipsilateral foot, and each stride's contralateral heel
    strike sample.

    Single support carries it all; over each double support it passes from the trailing to the leading
    foot along a smooth step (choice). Ipsilateral stance runs from heel strike (p = 0) to toe-off (the
    first sample whose warped phase reaches foot-off, as the ``TOE_OFF`` event); the contralateral foot
    leaves the ground when its own warped phase does, and lands at ``contra`` (``HEEL_STRIKE_CONTRA``).
    """
    p = np.broadcast_to(k.p, k.q.shape)
    i_to = np.argmax(k.q >= k.foot_off[:, None], axis=1)  # ipsilateral toe-off
    i_hc = np.argmin(np.abs(k.p[None, :] - k.contra[:, None]), axis=1)  # contralateral heel strike
    first_half = k.p[None, :] < 0.5
    i_tc = np.argmax(first_half & (k.qc >= k.foot_off[:, None]), axis=1)  # contralateral toe-off
    p_to, p_hc, p_tc = k.p[i_to][:, None], k.p[i_hc][:, None], k.p[np.maximum(i_tc, 1)][:, None]
    share = np.where(p < p_tc, smooth_step(p / p_tc), 1.0)
    share = np.where(p >= p_hc, 1.0 - smooth_step((p - p_hc) / np.maximum(p_to - p_hc, 1e-6)), share)
    return np.where(p >= p_to, 0.0, share), i_hc


def _com_vertical_acceleration(k: Kinematics) -> np.ndarray:
    """Second time derivative of the cohort's vertical centre-of-mass oscillation
    ``(A_z / 2) cos 4 pi (p - 0.30)`` within each stride."""
    w = 4 * np.pi / k.period[:, None]
    return -(k.z_amp / 2) * w**2 * np.cos(4 * np.pi * (k.p[None, :] - 0.30))


def _com_from_stance_foot(k: Kinematics, i_hc: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centre of mass relative to the stance foot: forward, lateral (+ left), up (m).

    The stance foot is the ipsilateral one from its heel strike (p = 0) and the contralateral one from
    its heel strike (``i_hc``); its contact point is where its heel was at touchdown, carried along the
    slope at belt speed. The centre of mass is ``COM_HEIGHT_FRAC`` of height above the floor plus the
    cohort's oscillation; the feet are ``STEP_WIDTH_M`` apart, the ipsilateral (right) one at -width/2.
    """
    n, m = k.t.shape
    rows = np.arange(n)
    r = np.radians(k.incline)[:, None]
    cheel_x, cheel_z = _heel_points(k, k.thigh_c, k.shank_c, k.foot_c)
    td_i = (k.heel_x[:, 0], k.heel_z[:, 0], k.t[:, 0])
    td_c = (cheel_x[rows, i_hc], cheel_z[rows, i_hc], k.t[rows, i_hc])
    contra_stance = np.arange(m)[None, :] >= i_hc[:, None]
    x0, z0, t0 = (np.where(contra_stance, c[:, None], i[:, None]) for i, c in zip(td_i, td_c, strict=True))
    belt = k.speed[:, None] * (k.t - t0)
    foot_x = x0 - belt * np.cos(r)
    foot_z = z0 - belt * np.sin(r)
    com_up = (COM_HEIGHT_FRAC - 0.530) * k.height + k.com_z
    foot_y = np.where(contra_stance, STEP_WIDTH_M / 2, -STEP_WIDTH_M / 2)
    return k.com_x - foot_x, k.com_y - foot_y, com_up - foot_z


def _heel_points(
    k: Kinematics, thigh: np.ndarray, shank: np.ndarray, foot: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The heel (sole, ``heel_back`` behind the ankle) of a leg with these angles, in the walker frame."""
    ankle_x, ankle_z = _ankle(k, thigh, shank)
    ft = np.radians(foot)
    return (
        ankle_x - k.heel_back * np.cos(ft) + k.ankle_height * np.sin(ft),
        ankle_z - k.heel_back * np.sin(ft) - k.ankle_height * np.cos(ft),
    )


def _knee(k: Kinematics, thigh: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    th = np.radians(thigh)
    return k.hip_x + k.thigh_length * np.sin(th), k.hip_z - k.thigh_length * np.cos(th)


def _ankle(k: Kinematics, thigh: np.ndarray, shank: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    knee_x, knee_z = _knee(k, thigh)
    sh = np.radians(shank)
    return knee_x + k.shank_length * np.sin(sh), knee_z - k.shank_length * np.cos(sh)


def _imu_points(k: Kinematics) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each IMU's mounting point (walker frame, m) by segment, from the true segment angles.

    The hip follows the centre of mass's smooth oscillation here, not the ground-contact hip of the heel
    signals: that one's height has a kink at every change of contact point (a rigid collision), which
    would put spikes of tens of m/s^2 into every segment's acceleration, the pelvis's included. Real
    walkers cushion it (heel pad, knee flexion); the cohort models no impact transient (docs/cohort.md).
    """
    k = replace(k, hip_x=k.com_x, hip_z=k.com_z)
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    px, py = PELVIS_IMU_M
    tilt = -np.radians(k.pelvis)  # anterior tilt turns the pelvis clockwise seen from the right
    out["pelvis"] = (
        k.hip_x + px * np.cos(tilt) - py * np.sin(tilt),
        k.hip_z + px * np.sin(tilt) + py * np.cos(tilt),
    )
    legs = (("", k.thigh, k.shank, k.foot), ("_contra", k.thigh_c, k.shank_c, k.foot_c))
    for side, thigh, shank, foot in legs:
        (s_th, c_th), (s_sh, c_sh), (s_ft, c_ft) = ((np.sin(a), np.cos(a)) for a in np.radians([thigh, shank, foot]))
        d = THIGH_IMU_FRAC * k.thigh_length
        out[f"thigh{side}"] = (k.hip_x + d * s_th, k.hip_z - d * c_th)
        knee_x, knee_z = k.hip_x + k.thigh_length * s_th, k.hip_z - k.thigh_length * c_th
        d = SHANK_IMU_FRAC * k.shank_length
        out[f"shank{side}"] = (knee_x + d * s_sh, knee_z - d * c_sh)
        ankle_x, ankle_z = knee_x + k.shank_length * s_sh, knee_z - k.shank_length * c_sh
        fx, fz = -k.heel_back, -k.ankle_height / 2  # back of the heel, in the foot's frame
        out[f"foot{side}"] = (ankle_x + fx * c_ft - fz * s_ft, ankle_z + fx * s_ft + fz * c_ft)
    return out

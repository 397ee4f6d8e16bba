"""Deterministic virtual cohort: clean sagittal gait of simulated adults over speeds and inclines.

No public gait data set can be downloaded where gaitscope is built, so its models train on this
generator. The realism argument, with every source and every modelling choice, is in
``docs/cohort.md``; in short:

* body size: leg length ~ N(0.88, 0.045) m clipped to [0.78, 0.98] (seed 000's cohort spans
  0.823-0.960 m), height = leg / 0.530 and segment lengths from Winter's anthropometric table;
* step length and stance fraction from Schwartz et al. 2008 as functions of dimensionless speed
  ``v / sqrt(g L)`` (Hof 1996 scaling); stride time = stride length / speed;
* joint-angle and ankle-moment curves: Schwartz 2008 class means interpolated in dimensionless speed;
* incline: foot rotated by the slope, thigh and shank shifted toward flexion uphill (most around
  heel strike), plantarflexor moment scaled with slope; linear in incline (a modelling choice);
* per subject: segment offsets, joint amplitude scales, a timing warp, step-length and moment scales
  (the kinds of variation gait fingerprints find, seed 004); per stride: stride time (CV 2 %),
  amplitude and offset deviations blended smoothly across heel strikes so no signal jumps.

Output is a LocoHub-style table (column names from :mod:`gaitscope.sessions.schema`), angles in radians, one
row per sample, ``samples_per_stride`` samples per stride including both ends. Signals are clean;
:func:`simulate_sensors` adds sensor noise. For schema version 2 of the sensor frame the table also
holds the reported contralateral leg (with the subject's between-leg asymmetry), the pelvis, the feet's
vertical loads, the centre of mass relative to the stance foot and each IMU's acceleration
(:mod:`gaitscope.sessions.synth.body`); their randomness has its own streams, so the columns above are unchanged.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Final

import numpy as np
import pandas as pd
from scipy.interpolate import CubicSpline

from gaitscope.sessions import schema as s
from gaitscope.sessions.synth.body import Kinematics, body_columns
from gaitscope.sessions.synth.normative import ANKLE, HIP, KNEE, MOMENT, PELVIS, at_speed, curve_spline, normative
from gaitscope.sessions.synth.sensors import SensorNoise, resample_walk, simulate_sensors

__all__ = [
    "GP_EKF_COHORT",
    "CohortSpec",
    "SensorNoise",
    "SubjectParams",
    "cohort_subject_metadata",
    "generate_cohort",
    "generate_walk",
    "make_subjects",
    "resample_walk",
    "simulate_sensors",
]

G = 9.81
#: Winter (2009) Fig. 4.1 segment lengths as fractions of height; hip height 0.530 H.
HIP_HEIGHT_FRAC, THIGH_FRAC, SHANK_FRAC, FOOT_FRAC, ANKLE_HEIGHT_FRAC = 0.530, 0.245, 0.246, 0.152, 0.039
#: Between-subject SDs, calibrated so the cohort's joint curves spread as Schwartz 2008's do
#: (``docs/cohort.md``): joint-excursion scale, and hip and knee posture offsets (deg).
AMPLITUDE_SD = 0.12
POSTURE_SD_DEG = (2.5, 4.0)
#: Heel (back of the calcaneus, on the sole) behind the ankle, as a fraction of foot length (choice).
HEEL_BACK_FRAC = 0.25
#: Phase window of level foot-flat whose mean foot angle is zeroed (centred on seed 000's p = 0.2).
FOOT_FLAT = (0.12, 0.28)
#: Forefoot contact point (metatarsal heads) from the heel, as a fraction of foot length (choice).
FOREFOOT_FRAC = 0.75
#: Incline response (deg of segment rotation per deg of slope): base + bump at heel strike (choice).
THIGH_GAIN, SHANK_GAIN = (1.1, 0.3), (0.55, 0.15)
BUMP_KAPPA = 6.0  # width of the heel-strike bump exp(kappa (cos 2 pi p - 1)): ~0.1 cycle
#: Fractional change of the plantarflexor moment per deg of slope (choice; sign from seed 000 Fig. 6).
MOMENT_PER_DEG = 0.02
#: Between-leg asymmetry of the knee and ankle excursions: ranges of the normalised symmetry index over
#: the gait cycle in 25 healthy adults (PMC8919661): knee -3.0..3.1 %, ankle -12..9.2 % (the hip's,
#: -1.5..1.1 %, is left out: the contralateral hip column predates the asymmetry and is kept as it was).
CONTRA_EXCURSION_RANGE = ((-0.030, 0.031), (-0.12, 0.092))
#: Orendurff et al. 2004: CoM peak-to-peak excursion (m) at 0.7 and 1.6 m/s.
COM_SPEEDS, COM_VERTICAL, COM_LATERAL = (0.7, 1.6), (0.027, 0.048), (0.070, 0.039)
#: Forward-speed fluctuation as a share of the ideal pendulum's g dz / v (choice).
PENDULUM_SHARE = 0.5
COM_PEAK_PHASE = 0.30  # CoM highest and over the stance foot at mid-stance


@dataclass(frozen=True)
class CohortSpec:
    """What to generate: subjects x speeds x inclines, strides per condition, and the seed."""

    n_subjects: int = 10
    speeds_m_s: tuple[float, ...] = (0.8, 1.0, 1.2)
    inclines_deg: tuple[float, ...] = (-10.0, -7.5, -5.0, -2.5, 0.0, 2.5, 5.0, 7.5, 10.0)
    strides_per_condition: int = 20
    samples_per_stride: int = 150
    seed: int = 20230101


#: What the GP-EKF's population model and control surface are fitted to (``sessions/registry.py``'s
#: ``gp_ekf_default``): level walking over seed 003's speeds (its treadmill ran 0.4-1.2 m/s).
GP_EKF_COHORT: Final = CohortSpec(
    n_subjects=6, speeds_m_s=(0.4, 0.6, 0.8, 1.0, 1.2), inclines_deg=(0.0,), strides_per_condition=4
)


@dataclass(frozen=True)
class SubjectParams:
    """One virtual subject; every field is drawn from the cohort seed by :func:`make_subjects`.

    Attributes:
        code: "VC01", "VC02", ...
        leg_length_m, height_m, mass_kg, bmi: body size (height = leg / 0.530, mass = BMI height^2).
        thigh_length_m, shank_length_m, foot_length_m, ankle_height_m: Winter's fractions of height.
        heel_back_m: heel behind the ankle (its depth below the ankle is ``ankle_height_m``).
        step_length_scale: multiplies Schwartz's step length at every speed (sd 5 %).
        timing_shift: cycle fraction by which mid-cycle features are delayed (sd 0.02); heel strike
            stays at phase 0.
        hip_/knee_/ankle_amplitude_scale: multiply each joint's excursion about its cycle mean (sd 12 %).
        hip_posture_deg, knee_posture_deg: constant offsets of the hip and knee angles (real posture,
            so the heel's kinematics follow); the ankle takes ``knee - hip`` so the foot still lies flat
            in mid-stance. With the amplitude scales these bring the cohort's between-subject SD of
            the joint curves to Schwartz 2008's (``docs/cohort.md``, calibration).
        moment_scale: multiplies the ankle moment per kg (sd 10 %).
        thigh_/shank_/foot_offset_deg: constant bias of the reported segment angles (marker placement
            and calibration; seed 004's first fingerprint). Not applied to the heel position.
        stride_time_cv: stride-to-stride coefficient of variation of stride time.
        stride_amplitude_cv: stride-to-stride sd of the joint-excursion and moment scales.
        stride_offset_deg: stride-to-stride sd of segment-angle offsets.
        stride_timing_sd: stride-to-stride sd of the timing warp (cycle fraction).
        contra_knee_excursion, contra_ankle_excursion: between-leg asymmetry, the contralateral knee's
            and ankle's excursion about their cycle means relative to the ipsilateral ones (0.02 = 2 %
            larger); drawn from their own stream (``docs/cohort.md``, schema version 2).
    """

    code: str
    leg_length_m: float
    mass_kg: float
    height_m: float
    bmi: float
    thigh_length_m: float
    shank_length_m: float
    foot_length_m: float
    ankle_height_m: float
    heel_back_m: float
    step_length_scale: float
    timing_shift: float
    hip_amplitude_scale: float
    knee_amplitude_scale: float
    ankle_amplitude_scale: float
    moment_scale: float
    thigh_offset_deg: float
    shank_offset_deg: float
    foot_offset_deg: float
    hip_posture_deg: float = 0.0
    knee_posture_deg: float = 0.0
    stride_time_cv: float = 0.02
    stride_amplitude_cv: float = 0.03
    stride_offset_deg: float = 0.5
    stride_timing_sd: float = 0.01
    contra_knee_excursion: float = 0.0
    contra_ankle_excursion: float = 0.0

    @property
    def metadata(self) -> str:
        """The ``subject_metadata`` string: ``leg_length_m:..,mass_kg:..,height_m:..``."""
        return f"leg_length_m:{self.leg_length_m!r},mass_kg:{self.mass_kg!r},height_m:{self.height_m!r}"


def _foot_flat_constant(spline: CubicSpline) -> float:
    """Mean level foot angle (deg) over FOOT_FLAT of the population curves: the standing offset."""
    j = spline(np.linspace(*FOOT_FLAT, 33))
    return float(np.mean(j[:, HIP] - j[:, PELVIS] - j[:, KNEE] + j[:, ANKLE]))


# --- subjects -----------------------------------------------------------------------------------
def make_subjects(spec: CohortSpec) -> list[SubjectParams]:
    """Draw ``spec.n_subjects`` subjects; subject i depends only on ``spec.seed`` and i."""
    out = []
    for i in range(spec.n_subjects):
        rng = np.random.default_rng(np.random.SeedSequence(spec.seed, spawn_key=(i, 0)))
        leg = float(np.clip(rng.normal(0.88, 0.045), 0.78, 0.98))
        bmi = float(np.clip(rng.normal(24.0, 2.5), 18.0, 32.0))
        z = rng.standard_normal(13)
        # Parameters added with schema version 2 come from their own stream, so the ones above keep theirs.
        extra = np.random.default_rng(np.random.SeedSequence(spec.seed, spawn_key=(i, 2)))
        knee_asym, ankle_asym = (float(extra.uniform(lo, hi)) for lo, hi in CONTRA_EXCURSION_RANGE)
        h = leg / HIP_HEIGHT_FRAC
        out.append(
            SubjectParams(
                code=f"VC{i + 1:02d}",
                leg_length_m=round(leg, 4),
                mass_kg=round(bmi * h * h, 2),
                height_m=round(h, 4),
                bmi=round(bmi, 3),
                thigh_length_m=THIGH_FRAC * h,
                shank_length_m=SHANK_FRAC * h,
                foot_length_m=FOOT_FRAC * h,
                ankle_height_m=ANKLE_HEIGHT_FRAC * h,
                heel_back_m=HEEL_BACK_FRAC * FOOT_FRAC * h,
                step_length_scale=float(1 + 0.05 * z[0]),
                timing_shift=float(np.clip(0.02 * z[1], -0.06, 0.06)),
                hip_amplitude_scale=float(1 + AMPLITUDE_SD * z[2]),
                knee_amplitude_scale=float(1 + AMPLITUDE_SD * z[3]),
                ankle_amplitude_scale=float(1 + AMPLITUDE_SD * z[4]),
                moment_scale=float(1 + 0.10 * z[5]),
                thigh_offset_deg=float(3.0 * z[6]),
                shank_offset_deg=float(2.0 * z[7]),
                foot_offset_deg=float(1.0 * z[8]),
                hip_posture_deg=float(POSTURE_SD_DEG[0] * z[11]),
                knee_posture_deg=float(POSTURE_SD_DEG[1] * z[12]),
                contra_knee_excursion=knee_asym,
                contra_ankle_excursion=ankle_asym,
            )
        )
    return out


# --- one walk -----------------------------------------------------------------------------------
def _fmt(x: float) -> str:
    return repr(float(round(x, 6)))


def _warp(p: np.ndarray, d: float | np.ndarray) -> np.ndarray:
    """Source phase for output phase p: mid-cycle features delayed by d, ends (and slopes) fixed."""
    return p - d * 0.5 * (1 - np.cos(2 * np.pi * p))


def _foot_points(
    subject: SubjectParams, thigh: np.ndarray, shank: np.ndarray, foot: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Heel and forefoot (x forward, z up; m) relative to the hip, from segment angles in deg."""
    th, sh, ft = np.radians(thigh), np.radians(shank), np.radians(foot)
    ax = subject.thigh_length_m * np.sin(th) + subject.shank_length_m * np.sin(sh)
    az = -subject.thigh_length_m * np.cos(th) - subject.shank_length_m * np.cos(sh)
    cf, sf, h = np.cos(ft), np.sin(ft), subject.ankle_height_m
    fore = FOREFOOT_FRAC * subject.foot_length_m - subject.heel_back_m
    return (
        ax - subject.heel_back_m * cf + h * sf,
        az - subject.heel_back_m * sf - h * cf,
        ax + fore * cf + h * sf,
        az + fore * sf - h * cf,
    )


# per-condition channels (one row per phase sample) that strides morph between at block changes
(
    C_PELVIS,
    C_HIP_M,
    C_HIP_D,
    C_KNEE_M,
    C_KNEE_D,
    C_ANKLE_M,
    C_ANKLE_D,
    C_MOM,
    C_TH_INC,
    C_SH_INC,
    C_FT_INC,
    C_FLAT,
    C_PELVIS_C,
    C_HIP_D_C,
    C_KNEE_D_C,
    C_ANKLE_D_C,
    C_TH_INC_C,
    C_SH_INC_C,
    C_Z_AMP,
    C_Y_AMP,
    C_DV,
    C_SPEED,
    N_CHAN,
) = range(23)


@dataclass(frozen=True)
class _Condition:
    """One (subject, speed, incline): spline of its curves and its per-condition constants."""

    subject: SubjectParams
    speed: float
    incline: float
    spline: CubicSpline
    mean: np.ndarray  # cycle means of CURVES
    flat: float  # standing offset of the foot angle, deg
    stride: float  # mean stride length, m
    foot_off: float  # stance fraction before the subject's timing warp
    contra: float  # contralateral heel strike, cycle fraction
    task: str
    task_id: str
    task_info: str

    def curves(self, q: np.ndarray, qc: np.ndarray) -> np.ndarray:
        """Channels at source phases ``q`` (ipsilateral) and ``qc`` (contralateral): (*q.shape, N_CHAN)."""
        sub, r = self.subject, self.incline
        j, jc = self.spline(q), self.spline(qc)
        bump = np.exp(BUMP_KAPPA * (np.cos(2 * np.pi * q) - 1))
        bump_c = np.exp(BUMP_KAPPA * (np.cos(2 * np.pi * qc) - 1))
        mom = j[..., MOMENT] * sub.moment_scale
        f = (self.speed - COM_SPEEDS[0]) / (COM_SPEEDS[1] - COM_SPEEDS[0])
        z_amp = COM_VERTICAL[0] + f * (COM_VERTICAL[1] - COM_VERTICAL[0])
        c = np.empty((*q.shape, N_CHAN))
        c[..., C_PELVIS], c[..., C_PELVIS_C] = j[..., PELVIS], jc[..., PELVIS]
        c[..., C_HIP_M] = self.mean[HIP] + sub.hip_posture_deg
        c[..., C_KNEE_M] = self.mean[KNEE] + sub.knee_posture_deg
        c[..., C_ANKLE_M] = self.mean[ANKLE] + sub.knee_posture_deg - sub.hip_posture_deg
        for ch, chc, k, scale in (
            (C_HIP_D, C_HIP_D_C, HIP, sub.hip_amplitude_scale),
            (C_KNEE_D, C_KNEE_D_C, KNEE, sub.knee_amplitude_scale),
            (C_ANKLE_D, C_ANKLE_D_C, ANKLE, sub.ankle_amplitude_scale),
        ):
            c[..., ch] = scale * (j[..., k] - self.mean[k])
            c[..., chc] = scale * (jc[..., k] - self.mean[k])
        c[..., C_MOM] = mom + MOMENT_PER_DEG * r * np.maximum(mom, 0.0)
        c[..., C_TH_INC] = r * (THIGH_GAIN[0] + THIGH_GAIN[1] * bump)
        c[..., C_TH_INC_C] = r * (THIGH_GAIN[0] + THIGH_GAIN[1] * bump_c)
        c[..., C_SH_INC] = r * (SHANK_GAIN[0] + SHANK_GAIN[1] * bump)
        c[..., C_SH_INC_C] = r * (SHANK_GAIN[0] + SHANK_GAIN[1] * bump_c)
        c[..., C_FT_INC] = r
        c[..., C_FLAT] = self.flat
        c[..., C_Z_AMP] = z_amp
        c[..., C_Y_AMP] = COM_LATERAL[0] + f * (COM_LATERAL[1] - COM_LATERAL[0])
        c[..., C_DV] = PENDULUM_SHARE * G * z_amp / self.speed
        c[..., C_SPEED] = self.speed
        return c


def _condition(subject: SubjectParams, speed: float, incline: float) -> _Condition:
    nv = normative()
    v_star = speed / np.sqrt(G * subject.leg_length_m)
    spline, mean = curve_spline(round(float(v_star), 9))
    stride = 2 * float(at_speed(nv.step, v_star)) * subject.leg_length_m * subject.step_length_scale
    task = "level_walking" if incline == 0 else "incline_walking" if incline > 0 else "decline_walking"
    return _Condition(
        subject,
        speed,
        incline,
        spline,
        mean,
        _foot_flat_constant(spline),
        stride,
        float(at_speed(nv.foot_off, v_star)),
        float(at_speed(nv.contra_contact, v_star)),
        task,
        f"s{_fmt(speed)}_i{_fmt(incline)}",
        f"speed_m_s:{_fmt(speed)},incline_deg:{_fmt(incline)}",
    )


def _blend(knots: np.ndarray, sb: np.ndarray) -> np.ndarray:
    """Per-stride values drawn at heel strikes, blended smoothly within each stride: (n, N, m)."""
    return knots[:-1, None, :] + (knots[1:] - knots[:-1])[:, None, :] * sb[None, :, None]


def _walk_columns(
    subject: SubjectParams,
    schedule: Sequence[tuple[float, float, int]],
    rng: np.random.Generator,
    n_per: int,
    t0: float,
    stride_scale: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    if n_per < 3:
        raise ValueError(f"samples_per_stride must be >= 3, got {n_per}")
    if not schedule:
        raise ValueError("schedule is empty")
    for v_block, _, n_block in schedule:
        if not (v_block > 0 and int(n_block) >= 1):
            raise ValueError(f"each block needs speed > 0 and n_strides >= 1, got {(v_block, n_block)}")
    p = np.linspace(0.0, 1.0, n_per)
    sb = 0.5 * (1 - np.cos(np.pi * p))  # 0 -> 1 with zero slope at both ends
    conds = [_condition(subject, float(v), float(r)) for v, r, _ in schedule]
    block = np.repeat(np.arange(len(schedule)), [int(n) for _, _, n in schedule])
    n = len(block)
    speed = np.array([float(schedule[int(b)][0]) for b in block])
    incline = np.array([float(schedule[int(b)][1]) for b in block])

    eps = rng.standard_normal(n)
    amp = _blend(rng.standard_normal((n + 1, 4)) * subject.stride_amplitude_cv, sb)
    off = _blend(rng.standard_normal((n + 1, 3)) * subject.stride_offset_deg, sb)
    jitter = _blend(rng.standard_normal((n + 1, 1)) * subject.stride_timing_sd, sb)[..., 0]
    shift = subject.timing_shift + jitter  # (n, N) timing warp of each sample

    stride_mean = np.array([conds[b].stride for b in block])
    if stride_scale is not None:
        scale = np.asarray(stride_scale, dtype=np.float64)
        if scale.shape != (n,) or not (np.isfinite(scale).all() and (scale > 0).all()):
            raise ValueError(f"stride_scale needs {n} finite values > 0 (one per stride), got shape {scale.shape}")
        stride_mean = stride_mean * scale
    period = stride_mean / speed * (1 + subject.stride_time_cv * eps)
    period = np.maximum(period, 0.2)
    stride_len = speed * period
    edges = t0 + np.concatenate([[0.0], np.cumsum(period)])
    t = edges[:-1, None] + p[None, :] * period[:, None]
    t[:, -1] = edges[1:]  # the shared boundary instant, bit-identical in both strides
    tp = period[:, None]

    # Condition curves at each stride's warped phases; a block's first stride morphs from the last one's.
    q, qc = _warp(p[None, :], shift), _warp((p[None, :] + 0.5) % 1.0, shift)
    cc = np.empty((n, n_per, N_CHAN))
    for b, cond in enumerate(conds):
        rows = block == b
        cc[rows] = cond.curves(q[rows], qc[rows])
        k = int(np.argmax(rows))
        if k > 0 and block[k - 1] != b:
            before = conds[int(block[k - 1])].curves(q[k], qc[k])
            cc[k] += (1 - sb)[:, None] * (before - cc[k])

    def ch(i: int) -> np.ndarray:
        return cc[:, :, i]

    def leg(
        hip_d: np.ndarray,
        knee_d: np.ndarray,
        ankle_d: np.ndarray,
        pelvis: np.ndarray,
        th_inc: np.ndarray,
        sh_inc: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """True (anatomical) thigh, shank, foot angles in deg, with stride deviations and incline."""
        hip = ch(C_HIP_M) + (1 + amp[..., 0]) * hip_d
        knee = ch(C_KNEE_M) + (1 + amp[..., 1]) * knee_d
        ankle = ch(C_ANKLE_M) + (1 + amp[..., 2]) * ankle_d
        thigh = hip - pelvis + off[..., 0] + th_inc
        shank = hip - pelvis - knee + off[..., 1] + sh_inc
        return thigh, shank, hip - pelvis - knee + ankle - ch(C_FLAT) + off[..., 2] + ch(C_FT_INC)

    thigh_t, shank_t, foot_t = leg(ch(C_HIP_D), ch(C_KNEE_D), ch(C_ANKLE_D), ch(C_PELVIS), ch(C_TH_INC), ch(C_SH_INC))
    thigh_c, shank_c, foot_c = leg(
        ch(C_HIP_D_C), ch(C_KNEE_D_C), ch(C_ANKLE_D_C), ch(C_PELVIS_C), ch(C_TH_INC_C), ch(C_SH_INC_C)
    )
    # The contralateral leg as reported: the subject's between-leg asymmetry on knee and ankle excursions
    # (thigh_c, shank_c, foot_c stay symmetric: the ground contact of the existing heel signals uses them).
    thigh_ca, shank_ca, foot_ca = leg(
        ch(C_HIP_D_C),
        (1 + subject.contra_knee_excursion) * ch(C_KNEE_D_C),
        (1 + subject.contra_ankle_excursion) * ch(C_ANKLE_D_C),
        ch(C_PELVIS_C),
        ch(C_TH_INC_C),
        ch(C_SH_INC_C),
    )
    thigh = thigh_t + subject.thigh_offset_deg  # reported angles carry the subject's constant bias
    shank = shank_t + subject.shank_offset_deg
    foot = foot_t + subject.foot_offset_deg
    moment = ch(C_MOM) * (1 + amp[..., 3])

    # CoM: vertical twice per stride (highest at mid-stance), lateral once, forward speed out of phase.
    w2 = 4 * np.pi * (p - COM_PEAK_PHASE)[None, :]
    w1 = 2 * np.pi * (p - COM_PEAK_PHASE)[None, :]
    za, ya, dv = ch(C_Z_AMP) / 2, ch(C_Y_AMP) / 2, ch(C_DV) / 2
    com_x = -dv * tp / (4 * np.pi) * np.sin(w2)
    com_v = ch(C_SPEED) - dv * np.cos(w2)
    com_y, com_vy = -ya * np.cos(w1), ya * 2 * np.pi / tp * np.sin(w1)
    com_z, com_vz = za * np.cos(w2), -za * 4 * np.pi / tp * np.sin(w2)

    # Heel: forward kinematics from the hip with the true angles of both legs. The hip moves forward
    # with the CoM and sits as high as the ground allows: the foot point (heel or forefoot, either leg)
    # that reaches lowest relative to the slope is on the ground.
    heel_x, heel_z, fore_x, fore_z = _foot_points(subject, thigh_t, shank_t, foot_t)
    points_c = _foot_points(subject, thigh_c, shank_c, foot_c)
    slope = np.tan(np.radians(ch(C_FT_INC)))
    points = ((heel_x, heel_z), (fore_x, fore_z), points_c[:2], points_c[2:])
    height = np.max([x * slope - z for x, z in points], axis=0)
    heel_x = com_x + heel_x
    hip_z = height - height.mean()
    heel_z = heel_z + hip_z

    hs, to, hs_c = np.zeros((n, n_per)), np.zeros((n, n_per)), np.zeros((n, n_per))
    hs[:, 0] = hs[:, -1] = 1.0  # both copies of the shared boundary instant carry the event
    rows = np.arange(n)
    to[rows, np.argmax(q >= np.array([conds[b].foot_off for b in block])[:, None], axis=1)] = 1.0
    contra = np.array([conds[b].contra for b in block])
    hs_c[rows, np.argmin(np.abs(p[None, :] - contra[:, None]), axis=1)] = 1.0
    step_len = np.concatenate([[stride_len[0] * (1 - contra[0])], stride_len[:-1] * (1 - contra[:-1])])
    body = body_columns(
        Kinematics(
            t=t, p=p, q=q, qc=qc, foot_off=np.array([conds[b].foot_off for b in block]), contra=contra,
            period=period, speed=speed, incline=incline, thigh=thigh_t, shank=shank_t, foot=foot_t,
            thigh_c=thigh_ca, shank_c=shank_ca, foot_c=foot_ca, pelvis=ch(C_PELVIS), hip_x=com_x, hip_z=hip_z,
            heel_x=heel_x, heel_z=heel_z, com_x=com_x, com_y=com_y, com_z=com_z, z_amp=ch(C_Z_AMP),
            thigh_length=subject.thigh_length_m, shank_length=subject.shank_length_m,
            heel_back=subject.heel_back_m, ankle_height=subject.ankle_height_m, height=subject.height_m,
            mass=subject.mass_kg,
        )
    )  # fmt: skip

    def per_sample(x: np.ndarray) -> np.ndarray:
        return np.repeat(x, n_per)

    def text(key: str) -> np.ndarray:
        return per_sample(np.array([getattr(conds[b], key) for b in block], dtype=object))

    rad = np.radians
    cols: dict[str, np.ndarray] = {
        s.SUBJECT: np.full(n * n_per, subject.code, dtype=object),
        s.SUBJECT_METADATA: np.full(n * n_per, subject.metadata, dtype=object),
        s.TASK: text("task"),
        s.TASK_ID: text("task_id"),
        s.TASK_INFO: text("task_info"),
        s.STEP: per_sample(np.arange(n, dtype=np.int64)),
        s.PHASE_IPSI: np.tile(100 * p, n),
        s.TIME_S: t,
        s.THIGH_ANGLE: rad(thigh),
        s.SHANK_ANGLE: rad(shank),
        s.FOOT_ANGLE: rad(foot),
        s.HIP_ANGLE: rad(thigh + ch(C_PELVIS)),
        s.KNEE_ANGLE: rad(thigh - shank),
        s.ANKLE_ANGLE: rad(foot - shank),
        s.HIP_ANGLE_CONTRA: rad(thigh_c + subject.thigh_offset_deg + ch(C_PELVIS_C)),
        s.HEEL_FORWARD: heel_x,
        s.HEEL_UP: heel_z,
        s.ANKLE_MOMENT: -moment * subject.mass_kg,
        s.COM_POSITION[0]: com_x,
        s.COM_POSITION[1]: com_y,
        s.COM_POSITION[2]: com_z,
        s.COM_VELOCITY[0]: com_v,
        s.COM_VELOCITY[1]: com_vy,
        s.COM_VELOCITY[2]: com_vz,
        s.HEEL_STRIKE: hs,
        s.TOE_OFF: to,
        s.HEEL_STRIKE_CONTRA: hs_c,
        s.STEP_LENGTH: per_sample(step_len),
        s.PHASE_RATE: per_sample(1 / period),
        s.STRIDE_LENGTH: per_sample(stride_len),
        s.INCLINE: per_sample(incline),
        s.SPEED: per_sample(speed),
        # schema version 2 (docs/cohort.md): the other leg as reported, pelvis, feet, centre of mass, IMUs
        s.THIGH_ANGLE_CONTRA: rad(thigh_ca + subject.thigh_offset_deg),
        s.SHANK_ANGLE_CONTRA: rad(shank_ca + subject.shank_offset_deg),
        s.FOOT_ANGLE_CONTRA: rad(foot_ca + subject.foot_offset_deg),
        s.KNEE_ANGLE_CONTRA: rad((thigh_ca + subject.thigh_offset_deg) - (shank_ca + subject.shank_offset_deg)),
        s.ANKLE_ANGLE_CONTRA: rad((foot_ca + subject.foot_offset_deg) - (shank_ca + subject.shank_offset_deg)),
        s.PELVIS_ANGLE: rad(ch(C_PELVIS)),
        **body,
    }
    return {
        k: (v if v.dtype == object or v.dtype == np.int64 else v.astype(np.float64).reshape(-1))
        for k, v in cols.items()
    }


def generate_walk(
    subject: SubjectParams,
    schedule: Sequence[tuple[float, float, int]],
    rng: np.random.Generator,
    samples_per_stride: int = 150,
    t0: float = 0.0,
    stride_scale: np.ndarray | None = None,
) -> pd.DataFrame:
    """One continuous walk: ``schedule`` blocks of ``(speed_m_s, incline_deg, n_strides)`` in order.

    ``samples_per_stride`` samples per stride including both ends (sample i at phase i/(N-1)), so the
    last sample of one stride and the first of the next are the same instant; ``time_s`` runs on from
    ``t0`` across strides and blocks and ``step`` counts strides from 0. The first stride of a new
    block morphs from the previous condition's curves to the new ones so no signal jumps.

    ``stride_scale`` (one value per stride, default 1) multiplies each stride's mean length at its speed;
    the stride time follows (length / speed), so the walker takes longer or shorter strides at the same
    speed, as when the step length leads a speed change (:mod:`gaitscope.sessions.synth.intent_walks`).
    """
    return pd.DataFrame(_walk_columns(subject, schedule, rng, samples_per_stride, t0, stride_scale))


def _condition_rng(spec: CohortSpec, i: int, speed: float, incline: float) -> np.random.Generator:
    key = (i, 1, round(speed * 10_000), round((incline + 90.0) * 10_000))
    return np.random.default_rng(np.random.SeedSequence(spec.seed, spawn_key=key))


def generate_cohort(spec: CohortSpec = CohortSpec()) -> pd.DataFrame:
    """Every subject x every (speed, incline) condition, each condition its own walk from time 0.

    Deterministic: subject i's parameters depend on ``(seed, i)`` and each condition's randomness on
    ``(seed, i, speed, incline)`` (``SeedSequence`` spawn keys), so any subset of a spec reproduces the
    same rows for the subjects and conditions it shares.
    """
    parts = [
        _walk_columns(
            subj,
            [(v, r, spec.strides_per_condition)],
            _condition_rng(spec, i, v, r),
            spec.samples_per_stride,
            0.0,
        )
        for i, subj in enumerate(make_subjects(spec))
        for v in spec.speeds_m_s
        for r in spec.inclines_deg
    ]
    if not parts:
        raise ValueError("spec has no subjects or no conditions")
    return pd.DataFrame({k: np.concatenate([part[k] for part in parts]) for k in parts[0]})


def cohort_subject_metadata(frame: pd.DataFrame) -> dict[str, dict[str, float]]:
    """Parse ``subject_metadata`` (``key:value,...``) once per subject."""
    out: dict[str, dict[str, float]] = {}
    pairs = frame[[s.SUBJECT, s.SUBJECT_METADATA]].drop_duplicates()
    for subject, text in zip(pairs[s.SUBJECT], pairs[s.SUBJECT_METADATA], strict=True):
        try:
            meta = {k.strip(): float(v) for k, v in (item.split(":", 1) for item in str(text).split(","))}
        except ValueError:
            raise ValueError(f"subject {subject}: malformed subject_metadata {text!r}") from None
        if str(subject) in out and out[str(subject)] != meta:
            raise ValueError(f"subject {subject} has more than one subject_metadata")
        out[str(subject)] = meta
    return out

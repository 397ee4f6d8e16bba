"""Sagittal segment angle and angular velocity from one raw 6-axis IMU: the IMU front end.

A device that sends raw gyro and accelerometer readings (``imu_{seg}_gyro_{x,y,z}_dps``,
``imu_{seg}_accel_{x,y,z}_m_s2``, axes of ``gaitscope.sessions.schema.CHANNELS``: x anterior, y along the segment
toward proximal, z to the right, so a (+) sagittal rotation is (+) about z and gravity reads
``(g sin a, g cos a, 0)`` at rest) gets its segment angle channels (``{seg}_angle_deg``,
``{seg}_vel_dps``) from :class:`ImuFrontEnd`, one per IMU (``imu_foot``, ``imu_shank``, ...). The stack
fills those channels only when the source does not send them, so ``hs_detector`` and ``phase_ekf`` after
it read them as if the device had sent angles.

The filter, per sample (``method="cf"``, the live default; ``docs/results.md`` compares it with the
libraries' AHRS filters on the cohort, ``gaitscope crossval --study imu``):

- **gyro bias**: the calibration's (:mod:`gaitscope.estimators.imu_calibration`), then tracked as the mean of the
  gyro over ``bias_tau_s`` (a segment's sagittal angle is periodic in walking, so its mean rate is 0): a
  first-order high-pass of the rate, as in Mayagoitia et al. 2002 (J Biomech 35:537-542);
- **angle**: the integrated rate, pulled toward the accelerometer's inclination ``atan2(a_x, a_y)`` with
  gain ``k_p`` (1/s) only while the accelerometer reads gravity alone (``| |a| - g | < accel_gate``,
  rate below ``rate_gate_dps``): a gated complementary filter (Mahony et al. 2008, IEEE TAC
  53:1203-1218, reduced to one axis; gating as Fusion's acceleration rejection, Madgwick et al. 2020);
- **foot**: at foot-flat (rate and specific force within the zero-velocity thresholds for
  ``zupt_samples`` samples: Skog et al. 2010, IEEE TBME 57:2657-2666) the angle is reset toward the
  accelerometer's inclination, which removes the integration drift stride by stride (Sabatini 2005,
  Med Biol Eng Comput 43:94-101, Fig. 2); toe-off is the foot rate's upward zero crossing after the
  push-off's negative peak (below ``-toe_off_dps``; Mariani et al. 2010, J Biomech 43:2999-3006). Heel
  strike is not duplicated here: ``hs_detector`` derives it from the foot channels this estimator fills;
- ``method="fusion"``: x-io's Fusion AHRS (``imufusion``, Madgwick et al. 2020) on the bias-corrected
  3-D signals, the sagittal angle from its gravity vector; the reference, compiled but about 3x slower.

Bad input never gives a non-finite output (the stack would fail the estimator): a missing or non-finite
reading holds the last angle and rate; a saturated gyro skips integration and leans on the
accelerometer; the output ``imu_code`` (unit ``code``, :data:`CODES`) says what happened at this sample.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import Final, Literal

import numpy as np
from numpy.typing import NDArray

from gaitscope.estimators.descriptor import Descriptor, Tunable, out
from gaitscope.estimators.protocol import MAX_GAP_S, Output, check_params, elapsed

__all__ = [
    "CODES",
    "G0",
    "SEGMENTS",
    "FrontEndConfig",
    "ImuFrontEnd",
    "descriptor",
    "imu_inputs",
    "inclination_deg",
]

Array = NDArray[np.float64]
#: Standard gravity (m/s^2).
G0: Final = 9.80665
#: Segments with a sagittal angle channel (``{seg}_angle_deg``) and an IMU (``imu_{seg}_...``).
SEGMENTS: Final = ("foot", "shank", "thigh", "foot_contra", "shank_contra", "thigh_contra")
#: ``imu_code`` values by index: 0 fine; 1 a reading missing or not finite (angle and rate held);
#: 2 gyro at full scale (rate held, angle from the accelerometer); 3 accelerometer implausible (below
#: 0.1 g, above full scale, or upside down along y for more than ``flip_s`` since it last read clearly
#: upright: a flipped or swapped axis);
#: 4 sample interval far from the configured one (a wrong sample rate); 5 gyro and accelerometer disagree
#: for more than ``flip_s`` (a flipped gyro axis, or a mounting far from the calibration).
CODES: Final = ("", "missing", "gyro_saturated", "accel_implausible", "sample_rate", "disagree")


def imu_inputs(segment: str) -> tuple[str, ...]:
    """The raw channels of a segment's IMU: gyro x, y, z then accelerometer x, y, z."""
    return (
        *(f"imu_{segment}_gyro_{a}_dps" for a in "xyz"),
        *(f"imu_{segment}_accel_{a}_m_s2" for a in "xyz"),
    )


def inclination_deg(accel_x: float, accel_y: float) -> float:
    """The sagittal angle (deg) a specific force ``(x, y)`` gives if it is gravity alone."""
    return math.degrees(math.atan2(accel_x, accel_y))


def _seg_side(segment: str) -> tuple[str, str]:
    base, _, side = segment.partition("_")
    return base, f"_{side}" if side else ""


@dataclass(frozen=True)
class FrontEndConfig:
    """Tuning of :class:`ImuFrontEnd` (every field a ``retune`` parameter).

    Attributes:
        pitch_offset_deg: mounting offset subtracted from the angle (from a standing calibration).
        gyro_bias_x_dps, gyro_bias_y_dps, gyro_bias_z_dps: initial gyro bias (from the calibration).
        bias_tau_s: time constant of the gyro-bias tracker (s; 0 keeps the calibration's bias).
        k_p: accelerometer correction gain (1/s) while the accelerometer reads gravity alone.
        accel_gate: largest ``| |a| - g |`` (m/s^2) at which the accelerometer corrects the angle.
        rate_gate_dps: largest rate (deg/s) at which it does.
        zupt_rate_dps, zupt_accel: foot-flat thresholds on the rate (deg/s) and ``| |a| - g |`` (m/s^2).
        zupt_samples: consecutive samples within them that make a foot-flat.
        zupt_gain: share of the gap to the inclination closed per foot-flat sample (0..1).
        toe_off_dps: push-off rate (deg/s, below minus this) that arms the toe-off detector.
        sample_period: the expected sample period (s); an interval off by more than half is flagged.
        gyro_full_scale_dps: the gyro's full scale (a reading at 98 % of it counts as saturated).
        flip_s: how long an upside-down accelerometer or a disagreement lasts before it is flagged.
    """

    pitch_offset_deg: float = 0.0
    gyro_bias_x_dps: float = 0.0
    gyro_bias_y_dps: float = 0.0
    gyro_bias_z_dps: float = 0.0
    bias_tau_s: float = 10.0
    k_p: float = 0.5
    accel_gate: float = 1.0
    rate_gate_dps: float = 60.0
    zupt_rate_dps: float = 40.0
    zupt_accel: float = 1.0
    zupt_samples: float = 3.0
    zupt_gain: float = 0.2
    toe_off_dps: float = 150.0
    sample_period: float = 0.01
    gyro_full_scale_dps: float = 2000.0
    flip_s: float = 1.0

    @classmethod
    def for_segment(cls, segment: str, **fields_: float) -> FrontEndConfig:
        """The defaults for a segment: the thigh's accelerometer corrects at every sample (ungated: its
        linear acceleration is small and averages out; gating it picks biased instants, 7.8 against 2.1
        deg RMSE on the cohort, ``docs/results.md``); feet and shanks gated."""
        base = cls(accel_gate=100.0, rate_gate_dps=1e4) if segment.startswith("thigh") else cls()
        return replace(base, **fields_)

    def check(self) -> None:
        """Raise ``ValueError`` for a value out of range."""
        for f in fields(self):
            v = getattr(self, f.name)
            if not math.isfinite(v):
                raise ValueError(f"{f.name} must be finite, got {v}")
        if min(self.bias_tau_s, self.k_p, self.accel_gate, self.zupt_accel, self.zupt_gain) < 0:
            raise ValueError(f"gains, gates and time constants must be >= 0: {self}")
        if self.zupt_gain > 1 or self.sample_period <= 0 or self.gyro_full_scale_dps <= 0 or self.flip_s <= 0:
            raise ValueError(f"zupt_gain must be <= 1; period, full scale and flip_s > 0: {self}")


class ImuFrontEnd:
    """One segment's IMU to its sagittal angle and rate, a stack estimator (``imu_{segment}``).

    Outputs: ``{seg}_angle{side}_deg``, ``{seg}_vel{side}_dps`` (channels: they fill the source's when it
    does not send them), ``imu_code`` (:data:`CODES`); a foot adds ``foot_flat`` and ``toe_off`` (bool).
    ``state`` is ``[angle (deg, before the offset), gyro bias z (deg/s)]``; no covariance.
    """

    optional_inputs: tuple[str, ...] = ()
    tunables: tuple[str, ...] = tuple(f.name for f in fields(FrontEndConfig))
    covariance = None

    def __init__(
        self,
        segment: str,
        config: FrontEndConfig | None = None,
        method: Literal["cf", "fusion"] = "cf",
        max_gap_s: float = MAX_GAP_S,
    ):
        if segment not in SEGMENTS:
            raise ValueError(f"no IMU front end for {segment!r}; segments are {', '.join(SEGMENTS)}")
        self.segment = segment
        self.config = config or FrontEndConfig.for_segment(segment)
        self.config.check()
        self.method = method
        self.max_gap_s = max_gap_s
        self.name = f"imu_{segment}"
        self.inputs = imu_inputs(segment)
        base, side = _seg_side(segment)
        self.is_foot = base == "foot"
        outs: list[Output] = [
            (f"{base}_angle{side}_deg", "deg"),
            (f"{base}_vel{side}_dps", "deg/s"),
            ("imu_code", "code"),
        ]
        if self.is_foot:
            outs += [("foot_flat", "bool"), ("toe_off", "bool")]
        self.outputs: tuple[Output, ...] = tuple(outs)
        self._fusion: object | None = None
        self._t: float | None = None
        self.reset()

    # --- protocol ---------------------------------------------------------------------------------
    @property
    def state(self) -> Array:
        return np.array([self._angle, self._bias[2]])

    def reset(self) -> None:
        c = self.config
        self._t = None
        self._start()
        self._bias = [c.gyro_bias_x_dps, c.gyro_bias_y_dps, c.gyro_bias_z_dps]

    def retune(self, **params: float) -> None:
        """Change :class:`FrontEndConfig` fields from the next sample on (a calibration's offsets, gains)."""
        check_params(self, params)
        config = replace(self.config, **params)
        config.check()
        c = self.config
        if (config.gyro_bias_x_dps, config.gyro_bias_y_dps, config.gyro_bias_z_dps) != (
            c.gyro_bias_x_dps,
            c.gyro_bias_y_dps,
            c.gyro_bias_z_dps,
        ):
            self._bias = [config.gyro_bias_x_dps, config.gyro_bias_y_dps, config.gyro_bias_z_dps]
        self.config = config

    def _start(self) -> None:
        """Forget the angle (the next good sample starts it from the accelerometer), keep the bias."""
        self._angle = math.nan
        self._rate = 0.0
        self._still = 0
        self._armed = False
        self._prev_rate = 0.0
        self._upside = 0.0
        self._disagree = 0.0
        self._fusion = None

    def step(self, t: float, z: Array) -> Array:
        """One sample: ``z`` = gyro x, y, z (deg/s), accelerometer x, y, z (m/s^2)."""
        dt, restart = elapsed(self._t, t, self.max_gap_s)
        if restart:
            self._start()
        self._t = t
        code, flat, toe = self._update(dt, z.tolist())
        angle = self._angle - self.config.pitch_offset_deg if self._angle == self._angle else 0.0
        angle = (angle + 180.0) % 360.0 - 180.0
        if self.is_foot:
            return np.array([angle, self._rate, float(code), flat, toe])
        return np.array([angle, self._rate, float(code)])

    # --- the filter -------------------------------------------------------------------------------
    def _update(self, dt: float, z: list[float]) -> tuple[int, float, float]:
        """Advance the filter; ``(code, foot_flat, toe_off)``. Plain float arithmetic (about a microsecond)."""
        c = self.config
        gx, gy, gz, ax, ay, az = z
        if not all(math.isfinite(v) and abs(v) < 1e6 for v in z):
            self._still = 0
            return 1, 0.0, 0.0
        code = 0
        if dt > 0 and abs(dt - c.sample_period) > 0.5 * c.sample_period:
            code = 4
        bias = self._bias
        if dt > 0 and c.bias_tau_s > 0:
            k = min(dt / c.bias_tau_s, 1.0)
            bias[0] += k * (gx - bias[0])
            bias[1] += k * (gy - bias[1])
            bias[2] += k * (gz - bias[2])
        saturated = max(abs(gx), abs(gy), abs(gz)) >= 0.98 * c.gyro_full_scale_dps
        rate = self._rate if saturated else gz - bias[2]
        norm = math.sqrt(ax * ax + ay * ay + az * az)
        incl = math.degrees(math.atan2(ax, ay))
        if norm < 0.1 * G0 or norm > 16.5 * G0:
            code = 3
            gravity = False
        else:
            gravity = abs(norm - G0) < c.accel_gate and abs(rate) < c.rate_gate_dps
        if self._angle != self._angle:  # (re)start: from the inclination, whatever it is
            self._angle = incl if code != 3 else 0.0
        elif self.method == "fusion" and not saturated and code != 3:
            self._angle = self._fusion_step(dt, gx - bias[0], gy - bias[1], rate, ax, ay, az)
        else:
            self._angle += rate * dt
            if gravity and not saturated:
                self._angle += min(c.k_p * dt, 1.0) * _wrap(incl - self._angle)
        if saturated:
            code = 2
            self._angle += min(5 * c.k_p * dt, 1.0) * _wrap(incl - self._angle)
        self._angle = _wrap(self._angle)
        self._rate = rate
        # flags held over time: upside down (a flipped axis), gyro and accelerometer disagreeing
        if dt > 0:
            # upside down: the time reading it since the last clear upright reading (in between, e.g. a segment
            # near horizontal or swinging hard, neither: a flipped shank's y reads above -0.5 g a few samples
            # per stride, which must not start the count again)
            if ay < -0.5 * G0:
                self._upside += dt
            elif ay > 0.5 * G0:
                self._upside = 0.0
            miss = gravity and abs(_wrap(incl - self._angle)) > 30.0
            self._disagree = self._disagree + dt if miss else max(self._disagree - dt / 4, 0.0)
        if self._upside > c.flip_s:
            code = 3
        elif self._disagree > c.flip_s and code == 0:
            code = 5
        if not self.is_foot:
            return code, 0.0, 0.0
        # foot-flat (zero-velocity update) and toe-off
        still = abs(rate) < c.zupt_rate_dps and abs(norm - G0) < c.zupt_accel and not saturated
        self._still = self._still + 1 if still else 0
        flat = self._still >= c.zupt_samples
        if flat:
            self._angle += c.zupt_gain * _wrap(incl - self._angle)
            self._armed = False
        toe = 0.0
        if rate < -c.toe_off_dps:
            self._armed = True
        elif self._armed and self._prev_rate < 0.0 <= rate:
            self._armed = False
            toe = 1.0
        self._prev_rate = rate
        return code, float(flat), toe

    def _fusion_step(self, dt: float, gx: float, gy: float, gz: float, ax: float, ay: float, az: float) -> float:
        """x-io Fusion (``imufusion``) on body axes (x, -z, y), so that gravity is +z (NWU) at rest."""
        import imufusion

        f = self._fusion
        if not isinstance(f, imufusion.Ahrs):
            f = imufusion.Ahrs()
            rate = 1.0 / self.config.sample_period
            f.set_settings(imufusion.AhrsSettings(sample_rate=rate, convention=imufusion.CONVENTION_NWU, gain=0.5,
                                                  gyroscope_range=self.config.gyro_full_scale_dps,
                                                  acceleration_rejection=90.0, magnetic_rejection=0.0,
                                                  rejection_timeout=int(5 * rate)))  # fmt: skip
            half = math.radians(self._angle) / 2
            f.set_quaternion(np.array([math.cos(half), 0.0, -math.sin(half), 0.0]))
            f.skip_startup()
            self._fusion = f
        if dt > 0:
            f.set_sample_period(dt)
            f.update_no_magnetometer(np.array([gx, -gz, gy]), np.array([ax, -az, ay]) / G0)
        g = f.get_gravity()
        return math.degrees(math.atan2(float(g[0]), float(g[2])))


def _wrap(deg: float) -> float:
    """An angle difference within [-180, 180)."""
    return (deg + 180.0) % 360.0 - 180.0


def descriptor(segment: str) -> Descriptor:
    """The front end of ``segment``'s IMU as a session and the views know it
    (:mod:`gaitscope.estimators.descriptor`): it derives the segment's angle channels a source may not send."""
    est = ImuFrontEnd(segment)
    meanings = {
        "imu_code": "what the front end did with this sample (gaitscope.estimators.imu_frontend.CODES)",
        "foot_flat": "the foot is flat on the ground (zero-velocity update)",
        "toe_off": "a toe-off on this sample",
    }
    return Descriptor(
        name=est.name,
        label=f"IMU front end ({segment.replace('_', ' ')})",
        inputs=est.inputs,
        optional_inputs=est.optional_inputs,
        outputs=tuple(out(name, unit, meanings.get(name)) for name, unit in est.outputs),
        tunables=tuple(Tunable(name) for name in est.tunables),
        derives=True,
        purpose=f"The {segment.replace('_', ' ')} angle and its rate from a raw 6-axis IMU, for a device that sends "
        "no angles.",
    )

"""Heel-strike detection from foot angle and angular velocity (seed 000 section II-E).

Hardware rule of the paper: all of ``0 < foot angle <= 30 deg``, foot angular velocity < 0, mean
absolute heel acceleration over the last 10 samples >= 10 m/s^2, and more than 0.4 s since the last
heel strike. Gaitscope applies the same angle, velocity and refractory tests at the sample where the
foot velocity turns negative (the foot angle's late-swing peak, which is where the heel lands), and
the acceleration test only when heel positions are given and ``accel_threshold`` is set: high-passed
positions carry no gravity and differentiating them twice is noisy, so by default it is off.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Final

import numpy as np
from numpy.typing import NDArray

from gaitscope.estimators.basis import Array
from gaitscope.estimators.channels import positions, span
from gaitscope.estimators.descriptor import Descriptor, Tunable, out
from gaitscope.estimators.protocol import HEEL_STRIKE, MAX_GAP_S, Output, check_params, elapsed

__all__ = ["DESCRIPTOR", "DetectorConfig", "HeelStrikeDetector"]

_INPUTS: Final = ("foot_angle_deg", "foot_vel_dps")
_OPTIONAL: Final = ("heel_forward_m", "heel_up_m")
#: Where :meth:`HeelStrikeDetector.step` finds each channel in ``z`` (its inputs, then its optional inputs).
_ANGLE, _VEL, _HEEL_FORWARD, _HEEL_UP = positions(
    (*_INPUTS, *_OPTIONAL), "foot_angle_deg", "foot_vel_dps", "heel_forward_m", "heel_up_m"
)
_HEEL: Final = span((*_INPUTS, *_OPTIONAL), "heel_forward_m", "heel_up_m")


@dataclass(frozen=True)
class DetectorConfig:
    """Heel-strike detection thresholds (seed 000 II-E).

    Attributes:
        max_foot_angle_deg: the foot angle must lie in (0, this].
        refractory_s: minimum time between heel strikes.
        accel_threshold: mean |heel acceleration| (m/s^2) over ``accel_window`` samples, or None to skip.
        accel_window: samples averaged for the acceleration test.
    """

    max_foot_angle_deg: float = 30.0
    refractory_s: float = 0.4
    accel_threshold: float | None = None
    accel_window: int = 10


class HeelStrikeDetector:
    """Streaming heel-strike detector from foot angle and angular velocity (and heel positions).

    Pipeline use: :meth:`detect`. Stack use (``hs_detector``): :meth:`step`, whose ``heel_strike``
    output fills that channel for the estimators after it when the source does not send it.
    """

    name = "hs_detector"
    inputs: tuple[str, ...] = _INPUTS
    optional_inputs: tuple[str, ...] = _OPTIONAL
    outputs: tuple[Output, ...] = ((HEEL_STRIKE, "bool"),)
    tunables: tuple[str, ...] = ("max_foot_angle_deg", "refractory_s", "accel_threshold")

    def __init__(self, config: DetectorConfig | None = None, max_gap_s: float = MAX_GAP_S):
        self.config = config or DetectorConfig()
        self.max_gap_s = max_gap_s
        self._t: float | None = None
        self._start()

    def _start(self) -> None:
        self._last_hs = -math.inf
        self._prev_vel = math.nan
        self._heel: list[Array] = []
        self._acc: list[float] = []

    def reset(self) -> None:
        self._start()
        self._t = None

    def retune(self, **params: float) -> None:
        """Change the thresholds of :class:`DetectorConfig` from the next sample on."""
        check_params(self, params)
        config = replace(self.config, **params)  # type: ignore[arg-type]  # only float fields are tunable
        if not (config.max_foot_angle_deg > 0 and config.refractory_s >= 0):
            raise ValueError(f"detector thresholds must be positive, got {config}")
        self.config = config

    @property
    def state(self) -> None:
        return None

    @property
    def covariance(self) -> None:
        return None

    def step(self, t: float, z: NDArray[np.float64]) -> NDArray[np.float64]:
        """The stack interface: ``z`` = foot angle, foot velocity, heel forward, heel up (raw, m);
        returns ``[1.0]`` at a heel strike, else ``[0.0]``. No foot angle or velocity: no heel strike."""
        dt, restart = elapsed(self._t, t, self.max_gap_s)
        if restart:
            self._start()
        self._t = t
        angle, vel = float(z[_ANGLE]), float(z[_VEL])
        if not (math.isfinite(angle) and math.isfinite(vel)):
            return np.zeros(1)
        heel = None
        if self.config.accel_threshold is not None and z.shape[0] >= _HEEL.stop:  # only the acceleration test
            heel = z[_HEEL] if math.isfinite(float(z[_HEEL_FORWARD])) and math.isfinite(float(z[_HEEL_UP])) else None
        return np.ones(1) if self.detect(t, dt, angle, vel, heel) else np.zeros(1)

    def detect(self, t: float, dt: float, foot_angle: float, foot_vel: float, heel: Array | None = None) -> bool:
        """Feed one sample; True when it is a heel strike."""
        cfg = self.config
        if cfg.accel_threshold is not None and heel is not None and dt > 0:
            self._heel.append(np.asarray(heel, dtype=np.float64))
            if len(self._heel) > 3:
                self._heel.pop(0)
            if len(self._heel) == 3:
                a = (self._heel[2] - 2 * self._heel[1] + self._heel[0]) / (dt * dt)
                self._acc.append(float(np.linalg.norm(a)))
                if len(self._acc) > cfg.accel_window:
                    self._acc.pop(0)
        turned = self._prev_vel >= 0.0 and foot_vel < 0.0
        self._prev_vel = foot_vel
        if not turned or not 0.0 < foot_angle <= cfg.max_foot_angle_deg:
            return False
        if t - self._last_hs <= cfg.refractory_s:
            return False
        if cfg.accel_threshold is not None:
            if not self._acc or float(np.mean(self._acc)) < cfg.accel_threshold:
                return False
        self._last_hs = t
        return True


#: The heel-strike detector as a session and the views know it (:mod:`gaitscope.estimators.descriptor`).
DESCRIPTOR: Final = Descriptor(
    name=HeelStrikeDetector.name,
    label="Heel-strike detector",
    inputs=HeelStrikeDetector.inputs,
    optional_inputs=HeelStrikeDetector.optional_inputs,
    outputs=(out(HEEL_STRIKE, "bool"),),
    tunables=(Tunable("max_foot_angle_deg"), Tunable("refractory_s", min=0.0), Tunable("accel_threshold")),
    purpose="Heel strikes from the foot angle and its velocity, for the estimators after it that need them.",
    paper="Medrano et al., IEEE T-RO 2023 (seed 000)",
)

"""The buttressed Kalman filter (seed 001) as a stack estimator: gait events from the sample stream.

:class:`IntentEstimator` (``intent`` in the registry) finds touchdowns and mid-stances in the samples a
device sends, feeds them to :class:`gaitscope.estimators.intent.ButtressedKF`, and holds and flags its estimate
when the events cannot be trusted (standing, walking backwards, a lost leg channel); beyond the paper.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Final

import numpy as np
from numpy.typing import NDArray

from gaitscope.estimators.channels import positions
from gaitscope.estimators.descriptor import Descriptor, PlotHint, Tunable, out
from gaitscope.estimators.intent import _VX, COHORT, BKFConfig, ButtressedKF
from gaitscope.estimators.intent_episodes import DEFAULT_RULE, EpisodeRule, SpeedEpisodes
from gaitscope.estimators.protocol import MAX_GAP_S, check_params

__all__ = [
    "COM_CHANNELS",
    "COM_LATERAL",
    "CONFIDENCE_SCALE",
    "DESCRIPTOR",
    "IntentEstimator",
]

Array = NDArray[np.float64]

#: The centre-of-mass channels the intent estimator needs (SensorFrame wire names): the sagittal ones, which
#: a device sends or :class:`gaitscope.estimators.com_kinematics.KinematicCoM` derives from leg kinematics.
COM_CHANNELS: Final = ("com_forward_m", "com_up_m", "com_forward_vel_m_s", "com_up_vel_m_s")
#: The lateral ones, used when sent (sagittal kinematics cannot give them).
COM_LATERAL: Final = ("com_lateral_m", "com_lateral_vel_m_s")
#: Channel values beyond these are treated as missing (absurd for a person walking): CoM position (m) and
#: velocity (m/s), foot force (N), hip-angle difference (deg), step length (m).
_MAX_COM, _MAX_FORCE_N, _MAX_HIP_DEG, _MAX_STEP_M = 100.0, 1e5, 360.0, 5.0
_INPUTS: Final = (*COM_CHANNELS, "hip_angle_deg", "hip_angle_contra_deg", "foot_force_N", "foot_force_contra_N",
                  "step_length_m")  # fmt: skip
_OPTIONAL: Final = (*COM_LATERAL, "foot_contact", "foot_contact_contra", "motor_current_A")
#: Where :meth:`IntentEstimator.step` finds each channel in ``z`` (its inputs, then its optional inputs).
_HIP, _HIP_C, _FORCE, _FORCE_C, _CONTACT, _CONTACT_C, _CURRENT, _STEP = positions(
    (*_INPUTS, *_OPTIONAL), "hip_angle_deg", "hip_angle_contra_deg", "foot_force_N", "foot_force_contra_N",
    "foot_contact", "foot_contact_contra", "motor_current_A", "step_length_m",
)  # fmt: skip
#: The centre-of-mass channels in the filter's order: forward, lateral, up position, then velocity.
_COM: Final = positions(
    (*_INPUTS, *_OPTIONAL), "com_forward_m", "com_lateral_m", "com_up_m", "com_forward_vel_m_s",
    "com_lateral_vel_m_s", "com_up_vel_m_s",
)  # fmt: skip


#: The filter's z-score over this is a z-score of steady walking's step-to-step changes (see
#: :class:`IntentEstimator`): fitted on the virtual cohort's 5-minute steady walks, all ten subjects
#: (``gaitscope crossval --study intent``, "Confidence"; fitted on nine subjects at a time: 2.81-2.87).
CONFIDENCE_SCALE: Final = 2.84


class IntentEstimator:
    """The buttressed Kalman filter as a stack estimator (``intent``): events from the sample stream.

    - Touchdown (seed 001 Sec. II-B): both feet's vertical force above ``contact_fraction`` of the largest
      force seen so far (5 %), or both contact flags when a device sends them; the rising edge of that
      double support is a touchdown, and the step length is the frame's ``step_length_m`` there.
    - Mid-stance: a zero crossing of ipsilateral minus contralateral hip angle, counted only once the
      difference has been more than ``hip_arm_deg`` away from zero since the last one (hysteresis without
      delay: sensor noise around zero while standing makes no mid-stances; a walking step swings it by
      tens of degrees).
    - Between events the outputs hold: desired speed, intent (the last mid-stance's change of desired
      speed), its class and confidence. The bookkeeping of a sample between events is a few float
      comparisons (no numpy).
    - The class (``intent_code``: 1 speeding up, -1 slowing down, 0 steady) is a speed-change **episode**
      (:class:`gaitscope.estimators.intent_episodes.SpeedEpisodes`, rule ``episodes``): it holds its sign
      from the step a change is called until the walker is steady again, so a change is one call (one
      event, one boost), and steady walking calls about once in five minutes or less on the cohort
      (``docs/results/intent.md``). The episode steps once per step, where the intent is read
      (``BKFConfig.intent_at``). With ``episodes=None`` the class is the per-step one of earlier versions
      and of the study's dead-band table: the step's change when it passes ``deadband_m_s`` with
      ``min_confidence`` standard deviations.
    - The confidence (``intent_confidence``) is the filter's z-score of the step's change divided by
      ``confidence_scale`` (:data:`CONFIDENCE_SCALE`), so that it means what it says on steady walking: the
      filter's own variance of ``v_x^d`` is too small by about that factor (on the cohort's steady walks 27 %
      of steps reach a raw "2 SD", against 4.6 % for a normal variable). The scale is fitted so that 4.6 %
      of steady steps reach 2; held out per subject by ``gaitscope crossval --study intent``.
    - The hip-motor current (``motor_current_A``, optional) feeds the iSCI variant's current model when
      the configuration has ``alpha``: its RMS over the swing before the touchdown.

    When the events cannot be trusted, the estimator **holds and flags**: desired speed and speed keep
    their last values, ``intent_m_s``, ``intent_code`` and ``intent_confidence`` are 0 (a confidence of 0
    is the flag: "not sure"), and the filter restarts at the next trustworthy mid-stance (as at the start
    of a walk, ``v_x^d = v_x``); codes come back after ``recover_steps`` more steps each with one
    touchdown and one mid-stance. The start of a walk is treated the same way: the desired speed starts at
    the first mid-stance's speed and its first steps settle it, so they get no code. That happens when

    - **standing**: no mid-stance for ``standing_s`` (2 s; a step at 0.4 m/s takes about 1 s), whatever
      the forces say (standing is double support throughout, so there is no touchdown either);
    - **not walking forwards**: the forward CoM velocity at a mid-stance is below ``min_speed_m_s``
      (0.1 m/s; walking backwards is negative): the step-length model (eq. 1) is for forward walking, so
      the filter is not updated;
    - **a lost leg channel**: a hip angle, or a foot force when no contact flags come, missing (NaN or
      absurd) for longer than ``max_dropout_s`` (a dropout of a sample or two only delays an event);
    - the filter's numbers stop being finite (a safety net; it restarts).

    A missed touchdown gives that step an intent of 0 with confidence 0 (the filter's rule), a doubled
    touchdown is ignored; neither needs a hold. A pause longer than :data:`MAX_GAP_S` restarts everything.
    Channel values beyond physical sense (CoM beyond 100 m or m/s, forces beyond 1e5 N, step lengths
    beyond 5 m) are treated as missing, so every output is always finite.
    """

    name = "intent"
    inputs: tuple[str, ...] = _INPUTS
    optional_inputs: tuple[str, ...] = _OPTIONAL
    outputs: tuple[tuple[str, str], ...] = (
        ("desired_speed_m_s", "m/s"),
        ("intent_m_s", "m/s"),
        ("intent_code", "code"),
        ("intent_confidence", "1"),
        ("speed_m_s", "m/s"),
    )
    tunables: tuple[str, ...] = ("threshold_m_s", "speed_threshold_m_s")

    def __init__(
        self,
        leg_length: float,
        config: BKFConfig = COHORT,
        contact_fraction: float = 0.05,
        deadband_m_s: float = 0.05,
        min_confidence: float = 2.0,
        *,
        confidence_scale: float = CONFIDENCE_SCALE,
        standing_s: float = 2.0,
        min_speed_m_s: float = 0.1,
        max_dropout_s: float = 0.05,
        hip_arm_deg: float = 2.0,
        recover_steps: int = 2,
        episodes: EpisodeRule | None = DEFAULT_RULE,
    ):
        self.filter = ButtressedKF(leg_length, config)
        self.episodes = SpeedEpisodes(episodes) if episodes is not None else None
        self.contact_fraction = contact_fraction
        self.deadband_m_s, self.min_confidence = deadband_m_s, min_confidence
        if not (math.isfinite(confidence_scale) and confidence_scale > 0):
            raise ValueError(f"confidence_scale must be a number > 0, got {confidence_scale}")
        self.confidence_scale = confidence_scale
        self.standing_s, self.min_speed_m_s = standing_s, min_speed_m_s
        self.max_dropout_s, self.hip_arm_deg, self.recover_steps = max_dropout_s, hip_arm_deg, recover_steps
        self.reset()

    @property
    def state(self) -> Array:
        return self.filter.z

    @property
    def covariance(self) -> Array:
        return self.filter.P

    @property
    def holding(self) -> bool:
        """True while the outputs are held and flagged (see the class docstring)."""
        return self._held or self._pending > 0

    def reset(self) -> None:
        self.filter.reset()
        self._t: float | None = None
        self._max_force = 0.0
        self._double = False
        self._hip_diff = math.nan
        self._armed = False
        self._current_sq, self._current_n = 0.0, 0
        self._out = np.zeros(5)
        self._last_mid = math.inf  # time of the last mid-stance (inf: none yet, set at the first sample)
        self._seen = math.inf  # time of the last sample with every event channel
        self._lost = False
        self._held = False  # holding: the next trustworthy mid-stance restarts the filter
        self._pending = self.recover_steps  # steps still to see before codes come back (none at the start)
        if self.episodes is not None:
            self.episodes.reset()

    def retune(self, **params: float) -> None:
        check_params(self, params)
        for k, v in params.items():
            if not v > 0:
                raise ValueError(f"{k} must be a number > 0, got {v}")
        if self.episodes is None:
            raise ValueError("this intent estimator calls per step (episodes=None): nothing to retune")
        episodes = self.episodes
        rule = episodes.rule
        episodes.rule = replace(
            rule,
            threshold_m_s=float(params.get("threshold_m_s", rule.threshold_m_s)),
            speed_threshold_m_s=float(params.get("speed_threshold_m_s", rule.speed_threshold_m_s)),
        )  # checks the rule

    @property
    def threshold_m_s(self) -> float:
        """The episode rule's threshold (a tunable; NaN without episodes)."""
        return self.episodes.rule.threshold_m_s if self.episodes is not None else math.nan

    @property
    def speed_threshold_m_s(self) -> float:
        """The episode rule's threshold on the measured speed (a tunable; NaN without episodes)."""
        return self.episodes.rule.speed_threshold_m_s if self.episodes is not None else math.nan

    def step(self, t: float, z: Array) -> Array:
        """One sample: ``z`` = the four sagittal CoM channels, both hip angles, both foot forces, the last
        step length, then the optional lateral CoM channels, contact flags and motor current (NaN: missing)."""
        last = self._t
        if last is None:
            self._last_mid = self._seen = t
        elif not t - last > 0:
            raise ValueError(f"time must increase: {t} after {last}")
        elif t - last > MAX_GAP_S:  # a pause: the walk starts over (as gaitscope.estimators.protocol.elapsed)
            self.reset()
            self._last_mid = self._seen = t
        self._t = t
        v = z.tolist()  # plain floats: a sample between events does no numpy
        hip_i, hip_c, f_i, f_c = v[_HIP], v[_HIP_C], v[_FORCE], v[_FORCE_C]
        contact_i, contact_c = v[_CONTACT], v[_CONTACT_C]
        if self._max_force < f_i < _MAX_FORCE_N:  # NaN compares False
            self._max_force = f_i
        if self._max_force < f_c < _MAX_FORCE_N:
            self._max_force = f_c
        if contact_i == contact_i and contact_c == contact_c:  # both flags sent (not NaN)
            double = contact_i > 0.5 and contact_c > 0.5
            forces = True
        else:
            limit = self.contact_fraction * self._max_force
            double = limit > 0 and limit < f_i < _MAX_FORCE_N and limit < f_c < _MAX_FORCE_N
            forces = -_MAX_FORCE_N < f_i < _MAX_FORCE_N and -_MAX_FORCE_N < f_c < _MAX_FORCE_N
        diff = hip_i - hip_c
        hip_ok = -_MAX_HIP_DEG < diff < _MAX_HIP_DEG
        if forces and hip_ok:
            self._seen = t
            if self._lost:
                self._lost = False
        elif t - self._seen > self.max_dropout_s and not self._lost:
            self._lost = True
            self._hip_diff, self._armed = math.nan, False  # no crossing across the gap
            self._hold()
        current = v[_CURRENT]
        if current == current and not double:
            self._current_sq += current * current
            self._current_n += 1
        if double and not self._double:
            self._touchdown(v[_STEP])
        self._double = double
        if hip_ok:
            if (diff > 0) != (self._hip_diff > 0) and self._armed:  # a NaN _hip_diff is never armed
                self._armed = False
                self._midstance(t, v)
            elif not self._armed and (diff > self.hip_arm_deg or diff < -self.hip_arm_deg):
                self._armed = True
            self._hip_diff = diff
        if t - self._last_mid > self.standing_s and not self._held:
            self._hold()  # standing (or a channel lost for good)
        return self._out.copy()

    def _touchdown(self, length: float) -> None:
        rms = math.sqrt(self._current_sq / self._current_n) if self._current_n else math.nan
        self._current_sq, self._current_n = 0.0, 0
        f = self.filter
        if not self._held and -_MAX_STEP_M < length < _MAX_STEP_M and f.touchdown(length, rms):
            if f.config.intent_at == "touchdown" and self._pending == 0:
                self._classify(True)  # the step's intent, a quarter step before its mid-stance

    def _midstance(self, t: float, v: list[float]) -> None:
        self._last_mid = t
        com = [x if -_MAX_COM < x < _MAX_COM else math.nan for x in [v[i] for i in _COM]]
        if com[3] < self.min_speed_m_s:  # not walking forwards (a lost velocity is NaN: updates the rest)
            self._hold()
            return
        f = self.filter
        if self._held:
            if self._lost:  # a channel is still lost: keep holding
                return
            f.reset()  # the walk starts over from this mid-stance
            self._held, self._pending = False, self.recover_steps
        counts = f.started and f.touched
        try:
            f.midstance(np.array(com))
        except np.linalg.LinAlgError:
            f.z[:] = math.nan  # caught below
        if not math.isfinite(f.desired_speed + f.intent + f.confidence + float(f.z[_VX])):
            f.reset()  # a safety net: restart at the next mid-stance
            self._hold()
            return
        if self._pending > 0:
            self._pending -= counts
            self._out[:] = (f.desired_speed, 0.0, 0.0, 0.0, float(f.z[_VX]))
            return
        self._classify(f.config.intent_at == "midstance")

    def _hold(self) -> None:
        """Hold desired speed and speed, flag intent, code and confidence 0 until the walk is trusted again."""
        self._held = True
        self._out[1:4] = 0.0
        if self.episodes is not None:
            self.episodes.reset()

    def _classify(self, new_step: bool) -> None:
        """The outputs after an update; ``new_step``: where the step's intent is read (the episode steps)."""
        f = self.filter
        speed = float(f.z[_VX])
        episodes = self.episodes
        if episodes is None:
            code = 0.0
            if abs(f.intent) >= self.deadband_m_s and f.confidence >= self.min_confidence:
                code = 1.0 if f.intent > 0 else -1.0
        else:
            code = float(episodes.step(f.desired_speed, speed) if new_step else episodes.code)
        self._out[:] = (f.desired_speed, f.intent, code, f.confidence / self.confidence_scale, speed)


#: The speed-change intent estimator as a session and the views know it
#: (:mod:`gaitscope.estimators.descriptor`); both plotted outputs hold between mid-stances.
DESCRIPTOR: Final = Descriptor(
    name=IntentEstimator.name,
    label="Speed-change intent (seed 001)",
    inputs=IntentEstimator.inputs,
    optional_inputs=IntentEstimator.optional_inputs,
    outputs=(
        out("desired_speed_m_s", "m/s", "the walker's desired speed, updated at every mid-stance"),
        out("intent_m_s", "m/s", "the last mid-stance's change of desired speed (0: not sure)"),
        out("intent_code", "code", "1 while a called speed-up lasts, -1 a slow-down, 0 steady or not sure"),
        out("intent_confidence", "1", "the change in standard deviations of steady steps' (0: held and flagged)"),
        out("speed_m_s", "m/s", "the centre of mass's forward speed at the last mid-stance"),
    ),
    quantities={"desired_speed_m_s": "desired_speed", "speed_m_s": "speed"},
    live=("intent_code", "intent_confidence"),  # the live view's indicator
    tunables=(Tunable("threshold_m_s", min=0.01, max=1.0), Tunable("speed_threshold_m_s", min=0.01, max=1.0)),
    plots=(
        PlotHint("intent", "Speed-change intent: desired vs actual speed", "m/s", ("desired_speed_m_s", "speed_m_s")),
    ),
    purpose="Whether the walker means to speed up or slow down, and the desired speed, at every mid-stance.",
    paper="Karulkar and Wensing 2021 (seed 001)",
)

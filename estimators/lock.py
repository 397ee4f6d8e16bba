"""Keeping the phase EKF on real walking: standing still, heel strikes from the shank, and lock loss.

Seed 000's filter assumes continuous walking with a foot sensor. Real walks stop, stand, restart and
lose sensors (issue #10). :class:`LockSupervisor` watches the samples the phase EKF gets and decides,
per sample (all thresholds are :class:`LockConfig` parameters):

- **standing**: every angular velocity present (foot, shank) below ``still_dps`` for ``still_s``. The
  phase is then held at its value when the stillness began, the phase rate is 0, and the torque goes to
  its standing value (0) over ``ramp_s``; once it is 0 the held phase becomes the standing posture's,
  ``resume_phase`` (0.3, mid-stance: someone standing has both feet in stance). Standing is a state, not
  an error: seed 003 holds its phase on a sudden stop the same way. Walking resumes when any of them
  exceeds ``move_dps``: the filters restart (as after a gap) at ``resume_phase`` (0.3: someone standing
  has both feet in stance, and walking starts from stance, whichever leg swings first; the first heel
  strike corrects it), advanced by the cadence times the time since the motion's onset (the last time
  the rates rose above ``onset_dps``, at most ``still_s`` back; ``backdate_resume``: walking began when the
  motion did, not when it became fast enough to be sure), with the cadence, stride length and incline of
  the last heel strike walked, and
  the torque ramps back in over ``ramp_s``; for ``heel_settle_s`` (2 s) the filter leaves out the heel
  positions, whose high-pass filter restarts and needs that long to settle.
- **the start's first quarter stride** (``advance_at_onset``): a leg leaving its standing posture turns
  slowly, and the truth advances by 0.1-0.2 cycle before any rate passes ``move_dps``; holding the phase
  until then was most of the starts' error (-10 to -14 % phase 0.1-0.3 s into a bout on the tuning
  cohort, below). So while standing, from the motion's onset on (any rate above ``onset_dps``) the phase
  reported is the one the restart would begin from at that sample (the posture's phase advanced at the
  last cadence since the onset), at that cadence; if the rates fall below ``onset_dps`` again (sway, a
  shift of weight) it returns to the held phase, and the filters are untouched until walking is
  confirmed. ``onset_dps`` (15 deg/s; it was ``still_dps``, 30) was chosen on a tuning cohort, never on
  the subjects the robust study scores: 10 subjects from cohort seed 4242 walking real walks of seed
  777 (``sessions/offline/robust_study.py``, ``TUNING``), the lowest of 20, 15 and 10 deg/s whose mean
  phase rate standing stayed within 0.005/s of the supervisor without the advance (10 deg/s raised it
  to 0.033-0.045/s: the standing noise crossed it). It is four times the cohort's standing noise on the
  shank gyro (sd 4 deg/s) and thirty times its gyro bias (sd 0.5 deg/s).
- **cadence changes** (``rate_noise_scale``): seed 000's phase rate follows a change of cadence over
  several strides (its process noise is tuned for the treadmill), and a walker who stops slows by a fifth
  or more within the last two strides; the phase then runs ahead (+8 to +12 % phase in the last slow
  stride on the tuning cohort, the stops' error) and, at a start, lags the second stride's faster cadence
  (-4 to -5 %). From the sample walking resumes for ``adapt_after_resume`` heel strikes, and for
  ``adapt_strides`` heel strikes after a stride ``cadence_change`` (4 %) longer or shorter than the one
  before it, the phase rate's process noise sd is ``rate_noise_scale`` (2) times the filter's (added to
  ``P`` after each update). On strides of steady length nothing changes; the cohort's steady strides vary by
  up to 5 % and detected heel strikes by a sample, so it also acts now and then in steady walking.
  Chosen on the tuning cohort (above) among 2, 3 and 4 x, 4 and 6 %, one and two strides, and 0 or 2
  strides after resuming: the lowest worst start or stop RMSE over the sensor subsets with steady walking
  and turns no more than 0.1 % worse in any subset, and no subject's condition more than about a point
  worse, for the EKF and its no-task ablation. 3 x gave better stops pooled but one tuning subject's
  no-task stops 5 points worse (4 x: the EKF's too); the faster rate follows the turns' yaw leak and a
  returning sensor's offset as well as the cadence.
- **heel strikes from the shank** when the foot sensor is missing: the shank's angular velocity swings
  forward (above ``shank_swing_dps``) in mid-swing and crosses zero just before the heel strikes
  (Aminian et al. 2002 and Salarian et al. 2004 take the minimum after the mid-swing peak; the zero
  crossing, about 20 ms earlier on the cohort, needs no look-ahead). Without it a shank-only walk gets no
  heel strike at all, and neither the backup filter nor the timing-based estimate can help.
- **lock lost**: while walking, no heel strike for ``max_stride_s``, or the filter's phase rate outside
  ``phase_rate_range`` for ``out_of_range_s``: the filter is reset from the heel-strike backup, else the
  timing-based estimate (what :meth:`gaitscope.estimators.pipeline.GaitStatePipeline.reset_from_backup` picks).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["LockConfig", "LockSupervisor", "ShankHeelStrike"]


@dataclass(frozen=True)
class LockConfig:
    """Thresholds of :class:`LockSupervisor` (see the module docstring); ``enabled`` False: none of it
    (seed 000's filter as published)."""

    enabled: bool = True
    still_dps: float = 30.0
    still_s: float = 0.7
    move_dps: float = 60.0
    ramp_s: float = 0.3
    resume_phase: float = 0.3
    heel_settle_s: float = 2.0
    shank_swing_dps: float = 150.0
    max_stride_s: float = 2.5
    phase_rate_range: tuple[float, float] = (0.3, 2.5)
    out_of_range_s: float = 1.0
    backdate_resume: bool = True
    onset_dps: float = 15.0
    advance_at_onset: bool = True
    rate_noise_scale: float = 2.0
    cadence_change: float = 0.04
    adapt_strides: int = 2
    adapt_after_resume: int = 2


class ShankHeelStrike:
    """Heel strikes from the shank's sagittal angular velocity: armed by a mid-swing peak above
    ``swing_dps``, fired at the next downward zero crossing."""

    def __init__(self, swing_dps: float = 150.0):
        self.swing_dps = swing_dps
        self._armed = False

    def step(self, shank_dps: float) -> bool:
        if shank_dps > self.swing_dps:  # NaN compares False
            self._armed = True
            return False
        if self._armed and shank_dps < 0.0:
            self._armed = False
            return True
        return False


class LockSupervisor:
    """Per-sample state of one walker (see the module docstring).

    Attributes:
        standing: True while standing still was detected (and not yet left).
        standing_weight: 0 walking, 1 standing, ramping between over ``ramp_s``.
        held_phase: the phase held while standing.
    """

    def __init__(self, config: LockConfig | None = None):
        self.config = config or LockConfig()
        self.reset()

    def reset(self) -> None:
        self.shank = ShankHeelStrike(self.config.shank_swing_dps)
        self.standing = False
        self.standing_weight = 0.0
        self.held_phase = 0.0
        self._still_since: float | None = None
        self._still_phase = 0.0
        self._changed_t = -math.inf
        self._last_hs: float | None = None
        self._out_since: float | None = None
        #: While standing: when the angular velocities last rose above ``onset_dps`` (the motion's onset).
        self.onset: float | None = None
        self._hs1 = self._hs2 = 0.0  # the last two heel strikes walked (since walking resumed)
        self._hs_seen = 0
        #: Heel strikes left until the phase rate adapts at its usual speed again (``rate_noise_scale``).
        self.adapt_left = 0

    def motion(self, t: float, foot_dps: float, shank_dps: float, phase: float) -> str:
        """Update the standing state from this sample's angular velocities (NaN: that sensor is missing)
        and the filter's phase before it; returns ``"standing"`` on the sample standing is detected,
        ``"resumed"`` on the one walking resumes, else ``""``."""
        c = self.config
        if not c.enabled:
            return ""
        rates = [abs(v) for v in (foot_dps, shank_dps) if v == v]
        event = ""
        if rates:
            fastest = max(rates)
            if self.standing:
                if fastest < c.onset_dps or self.onset is None:
                    self.onset = None if fastest < c.onset_dps else t
                if fastest > c.move_dps:
                    self.standing, self._changed_t, event = False, t, "resumed"
                    self._still_since = None
                    self._last_hs = t  # a fresh start: no heel strike is overdue yet
                    self._hs_seen, self.adapt_left = 0, c.adapt_after_resume
            elif fastest < c.still_dps:
                if self._still_since is None:
                    self._still_since, self._still_phase = t, phase
                elif t - self._still_since >= c.still_s:
                    self.standing, self._changed_t, event = True, t, "standing"
                    self.held_phase = self._still_phase
            else:
                self._still_since = None
        ramp = min(1.0, (t - self._changed_t) / c.ramp_s) if c.ramp_s > 0 else 1.0
        self.standing_weight = ramp if self.standing else 1.0 - ramp
        if self.standing and ramp >= 1.0:  # the torque is out: stand at the posture's phase
            self.held_phase = c.resume_phase
        return event

    def adapting(self, t: float, heel_strike: bool) -> bool:
        """While walking, after the filter's step: whether the phase rate adapts faster on this sample (the
        cadence is changing: walking resumed ``adapt_after_resume`` heel strikes ago or less, or the stride
        that ended at most ``adapt_strides`` heel strikes ago was ``cadence_change`` longer or shorter than the
        one before it)."""
        c = self.config
        if not c.enabled or self.standing:
            return False
        if heel_strike:
            if self.adapt_left > 0:
                self.adapt_left -= 1
            if self._hs_seen >= 2 and abs((t - self._hs1) / (self._hs1 - self._hs2) - 1.0) > c.cadence_change:
                self.adapt_left = max(self.adapt_left, c.adapt_strides)
            self._hs2, self._hs1 = self._hs1, t
            self._hs_seen = min(self._hs_seen + 1, 2)
        return self.adapt_left > 0

    def lost(self, t: float, heel_strike: bool, phase_rate: float) -> str:
        """While walking: why the filter lost track at this sample (``""``: it did not)."""
        c = self.config
        if not c.enabled:
            return ""
        if heel_strike or self._last_hs is None:
            self._last_hs = t
        if self.standing:
            self._out_since = None
            return ""
        if t - self._last_hs > c.max_stride_s:
            self._last_hs = t
            return f"no heel strike for {c.max_stride_s:g} s"
        lo, hi = c.phase_rate_range
        if lo <= phase_rate <= hi:
            self._out_since = None
        elif self._out_since is None:
            self._out_since = t
        elif t - self._out_since > c.out_of_range_s:
            self._out_since = None
            return f"phase rate {phase_rate:.2f}/s outside {lo:g}..{hi:g} for {c.out_of_range_s:g} s"
        return ""

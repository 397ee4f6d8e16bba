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
  the rates rose above ``still_dps``, at most ``still_s`` back; ``backdate_resume``: walking began when the
  motion did, not when it became fast enough to be sure), with the cadence, stride length and incline of
  the last heel strike walked, and
  the torque ramps back in over ``ramp_s``; for ``heel_settle_s`` (2 s) the filter leaves out the heel
  positions, whose high-pass filter restarts and needs that long to settle.
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
        #: While standing: when the angular velocities last rose above ``still_dps`` (the motion's onset).
        self.onset: float | None = None

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
                if fastest < c.still_dps or self.onset is None:
                    self.onset = None if fastest < c.still_dps else t
                if fastest > c.move_dps:
                    self.standing, self._changed_t, event = False, t, "resumed"
                    self._still_since = None
                    self._last_hs = t  # a fresh start: no heel strike is overdue yet
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

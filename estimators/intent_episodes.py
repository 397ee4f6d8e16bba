"""Speed-change episodes: one call per change of speed, from the buttressed Kalman filter's step estimates.

Seed 001 reads intent as the change of the desired speed ``v_x^d`` over one step and scores its sign on
every step; it names no rule for *calling* a change, which a live view, an event log and the intent gain
boost need. Calling each step whose change passes a dead band calls about one steady step in seven on
the virtual cohort (``docs/results/intent.md``): a step's ``v_x^d`` carries the step length's
stride-to-stride noise, amplified by ``1 / kappa_2`` (about 3). :class:`SpeedEpisodes` calls episodes
instead (beyond the paper; every number below is a parameter of :class:`EpisodeRule`):

- two **signals** per step: the filter's desired speed ``v_x^d``, which leads, and the measured forward
  speed ``v_x``, which lags a step but is far less noisy;
- each one's **reference** is its mean over the last ``window_steps`` steady steps (at least ``min_steps``
  of them: seed 001's commands come at step 7 or 8, after the filter's first steps settle);
- an **episode opens** on the first step whose desired speed is ``threshold_m_s`` or more from its
  reference, or whose measured speed is ``speed_threshold_m_s`` or more from its own (``inf``: the
  filter alone; an infinite ``threshold_m_s`` with a finite ``speed_threshold_m_s`` is the baseline "the
  speed changed"), with that deviation's sign (1 speeding up, -1 slowing down; the desired speed's when
  both pass), and holds that code while it lasts: one call per change, however many steps it takes;
- it **closes** once the desired speed has changed by less than ``settle_m_s`` on ``settle_steps`` steps
  in a row (the walker is steady at the new speed), or after ``max_steps`` steps; the references then
  start over from the new speed, ``min_steps`` steps before the next episode can open.

The defaults are the choice of ``gaitscope crossval --study intent``'s nested leave-one-subject-out
selection on all ten cohort subjects (most commanded changes caught on time at no more than one call per
five minutes of steady walking); the held-out figures are in ``docs/results/intent.md``.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Final

__all__ = ["DEFAULT_RULE", "EpisodeRule", "SpeedEpisodes"]


@dataclass(frozen=True)
class EpisodeRule:
    """When a change of speed is called (see the module docstring).

    Attributes:
        threshold_m_s: deviation of a step's desired speed from its reference that opens an episode (m/s).
        speed_threshold_m_s: the same for the measured speed (m/s; ``inf``: not used).
        window_steps: steady steps the reference averages at most.
        min_steps: steady steps the reference needs before an episode can open.
        settle_m_s: a step whose signal changed by less than this is a steady one (m/s).
        settle_steps: steady steps in a row that close an episode.
        max_steps: the longest episode, in steps.
    """

    threshold_m_s: float = 0.11
    speed_threshold_m_s: float = 0.08
    window_steps: int = 8
    min_steps: int = 3
    settle_m_s: float = 0.03
    settle_steps: int = 2
    max_steps: int = 12

    def __post_init__(self) -> None:
        for name in ("threshold_m_s", "speed_threshold_m_s"):
            v = getattr(self, name)
            if not v > 0:  # NaN too
                raise ValueError(f"{name} must be > 0 (inf: not used), got {v}")
        if not (math.isfinite(self.settle_m_s) and self.settle_m_s >= 0):
            raise ValueError(f"settle_m_s must be a number >= 0, got {self.settle_m_s}")
        if not 1 <= self.min_steps <= self.window_steps or self.settle_steps < 1 or self.max_steps < self.settle_steps:
            raise ValueError("need 1 <= min_steps <= window_steps, settle_steps >= 1 and max_steps >= settle_steps")


#: The shipped rule (the module docstring says where it comes from).
DEFAULT_RULE: Final = EpisodeRule()


class SpeedEpisodes:
    """Calls speed-change episodes step by step (see the module docstring); a few float operations a step.

    Attributes:
        code: 1 while a speeding-up episode lasts, -1 while a slowing-down one lasts, else 0.
        deviation: the last step's desired speed minus its reference (m/s; 0 while the reference fills).
    """

    def __init__(self, rule: EpisodeRule = DEFAULT_RULE):
        self.rule = rule
        self.reset()

    def reset(self) -> None:
        """Forget the walk: no episode, an empty reference."""
        self.code = 0
        self.deviation = 0.0
        self._window: deque[float] = deque(maxlen=self.rule.window_steps)
        self._speeds: deque[float] = deque(maxlen=self.rule.window_steps)
        self._last = math.nan
        self._steady = 0
        self._steps = 0

    def step(self, desired_m_s: float, speed_m_s: float) -> int:
        """One step's desired and measured speed (m/s); the code after it. Non-finite input: the walk
        starts over (no call)."""
        r = self.rule
        x, v = desired_m_s, speed_m_s
        if not math.isfinite(x + v):
            self.reset()
            return 0
        window, speeds = self._window, self._speeds
        if self.code:
            self._steps += 1
            self._steady = self._steady + 1 if abs(x - self._last) < r.settle_m_s else 0
            self._last = x
            if self._steady >= r.settle_steps or self._steps >= r.max_steps:
                self.code = 0
                window.clear()
                speeds.clear()
                window.append(x)
                speeds.append(v)
            return self.code
        if len(window) >= r.min_steps:
            self.deviation = d = x - sum(window) / len(window)
            dv = v - sum(speeds) / len(speeds)
            if abs(d) >= r.threshold_m_s or abs(dv) >= r.speed_threshold_m_s:
                self.code = (1 if d > 0 else -1) if abs(d) >= r.threshold_m_s else (1 if dv > 0 else -1)
                self._last, self._steady, self._steps = x, 0, 0
                return self.code
        window.append(x)
        speeds.append(v)
        return 0

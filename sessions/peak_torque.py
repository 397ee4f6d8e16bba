"""The peak ankle torque a session's settings command over one stride, at a gait state: what a clinician is
asked to confirm before a change that can raise the torque (:mod:`gaitscope.sessions.live.torque_rule`).

The command is the stack's (:meth:`gaitscope.sessions.stack.EstimatorStack._command`)::

    tau(p) = clip(profile(p, l, r) x mass x gain x (1 + boost), 0, max_torque)

over the phases ``p`` of a stride at one stride length ``l`` (leg lengths) and incline ``r`` (deg): the
session's current ones when its primary estimates them, else the nominal ones the torque profile assumes
(:data:`~gaitscope.sessions.stack.NOMINAL_STRIDE` leg lengths on level ground). ``boost`` is the intent boost
at its largest (``intent_gain_boost``: full confidence that the walker speeds up), so the peak is the most the
settings can command at that state. A primary with its own torque command (``torque_Nm``, seed 003's
``gp_ekf``) has no profile to evaluate here: its peak is taken as the bound, the most it may command.

Pure: numbers in, a number out (N m, finite, within ``[0, max_torque]``).
"""

from __future__ import annotations

import math
from typing import Final

import numpy as np

from gaitscope.estimators.torque import TorqueProfile
from gaitscope.sessions.stack import NOMINAL_STRIDE

__all__ = ["PHASES", "peak_torque"]

#: Phases the peak is searched over: every 1/1000 of a stride (the profile's plantarflexion peak is ~10 %
#: of the stride wide, so the grid's maximum is within a fraction of a percent of the true one).
PHASES: Final = np.linspace(0.0, 1.0, 1001)


def peak_torque(
    profile: TorqueProfile | None,
    *,
    mass_kg: float,
    stride_legs: float,
    incline_deg: float,
    torque_gain: float,
    max_torque_Nm: float,
    intent_gain_boost: float = 0.0,
) -> float:
    """The largest torque (N m) the settings command over a stride at one gait state.

    Args:
        profile: the session's torque profile; None: the primary commands its own torque (the peak is the bound).
        mass_kg: the subject's mass.
        stride_legs, incline_deg: the gait state (stride length in leg lengths, incline in degrees); a
            non-finite one counts as the nominal state's (1.3 leg lengths, level), as the stack's command does.
        torque_gain, max_torque_Nm, intent_gain_boost: the settings.
    """
    bound = max(0.0, float(max_torque_Nm))
    if profile is None:
        return bound
    l_norm = stride_legs if math.isfinite(stride_legs) else NOMINAL_STRIDE
    r = incline_deg if math.isfinite(incline_deg) else 0.0
    gain = max(0.0, torque_gain) * (1.0 + max(0.0, intent_gain_boost))
    n = len(PHASES)
    tau = profile.torque(PHASES, np.full(n, l_norm), np.full(n, r), mass_kg * gain, bound)
    peak = float(np.max(tau))
    return peak if math.isfinite(peak) else 0.0

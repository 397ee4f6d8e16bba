"""The one rule for settings changes that can raise the torque on the person, whoever sends them (the
dashboard, an API client, an undo).

A change **raises** when it raises the torque gain, the maximum torque or the intent boost, or switches the
primary estimator (which changes what drives the torque: another phase, another gait state, another control
surface). Such a change

- needs ``confirm`` (:attr:`~gaitscope.sessions.schema.SettingsChange.confirm`): without it, it is refused with
  the peak torque before and after (a 409 whose detail is a :class:`~gaitscope.sessions.schema.TorqueRaiseRefused`),
  for the client to show and resend confirmed;
- is made at most once every :data:`~gaitscope.sessions.schema.TORQUE_RAISE_INTERVAL_S` seconds of the session's
  clock (the refusal says when it may be made), confirmed or not.

:func:`refusal` is the rule, pure; :class:`~gaitscope.sessions.live.settings_change.SettingsChanges` applies it to
every change of a running session.

A change that only lowers (or leaves) the gain, the bound and the boost and keeps the primary never asks and is
never held back, by this rule or by the rates of change of the settings (a clinician must always be able to
lower). The noise scales tune the estimators' filters, not the torque command; they keep their own rates of
change and need no confirmation.

The peaks are :func:`~gaitscope.sessions.peak_torque.peak_torque` at the session's gait state: the stride length
and incline of the primary (before: the one now; after: the one the change makes primary) from its last
outputs, the nominal ones where it estimates none (or has no outputs yet).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Final

from gaitscope.estimators.torque import TorqueProfile
from gaitscope.sessions import schema
from gaitscope.sessions.peak_torque import peak_torque
from gaitscope.sessions.schema import SessionSettings

__all__ = ["RAISING", "GaitState", "TorqueRaise", "assess", "raising_fields", "refusal"]

#: The numeric settings whose rise raises the torque (besides a switch of the primary).
RAISING: Final = ("torque_gain", "max_torque_Nm", "intent_gain_boost")


@dataclass(frozen=True)
class GaitState:
    """What the peak of one primary is computed from: its torque profile (None: the primary commands its own
    torque), and the stride length (leg lengths) and incline (deg) it stands at (NaN: unknown, the nominal
    ones). ``commands``: False when no estimator drives the torque (a failed primary without a fallback: 0)."""

    profile: TorqueProfile | None
    stride_legs: float
    incline_deg: float
    commands: bool = True


@dataclass(frozen=True)
class TorqueRaise:
    """A change's effect on the torque: the settings that can raise it (empty: it cannot) and the peaks (N m)."""

    fields: list[str]
    peak_before_Nm: float
    peak_after_Nm: float


def raising_fields(current: SessionSettings, updates: dict[str, Any]) -> list[str]:
    """The settings of ``updates`` (field -> new value, only those that change) that can raise the torque."""
    out: list[str] = [k for k in RAISING if k in updates and updates[k] > getattr(current, k)]
    if "primary" in updates and updates["primary"] != current.primary:
        out.append("primary")
    return out


def _peak(s: SessionSettings, state: GaitState, mass_kg: float) -> float:
    if not state.commands:
        return 0.0
    return peak_torque(
        state.profile,
        mass_kg=mass_kg,
        stride_legs=state.stride_legs,
        incline_deg=state.incline_deg,
        torque_gain=s.torque_gain,
        max_torque_Nm=s.max_torque_Nm,
        intent_gain_boost=s.intent_gain_boost,
    )


def assess(
    current: SessionSettings,
    new: SessionSettings,
    fields: list[str],
    state_before: GaitState,
    state_after: GaitState,
    mass_kg: float,
) -> TorqueRaise:
    """The peaks of a change from ``current`` to ``new`` whose torque-raising settings are ``fields``."""
    before = _peak(current, state_before, mass_kg)
    after = _peak(new, state_after, mass_kg)
    return TorqueRaise(fields, round(before, 2), round(after, 2))


def refusal(
    raise_: TorqueRaise, confirm: bool, now: float, last_raise: float | None, interval: float
) -> schema.TorqueRaiseRefused | None:
    """The rule applied to a change that can raise the torque (``raise_.fields`` not empty): why it is refused
    (None: it may be made). ``now``, ``last_raise`` (the last such change; None: none yet): the session's clock.

    Too soon (less than ``interval`` seconds since the last such change) comes first, confirmed or not; then
    the want of a confirmation.
    """
    what = ", ".join(raise_.fields)
    peaks = f"peak torque {raise_.peak_before_Nm:.1f} -> {raise_.peak_after_Nm:.1f} N m"
    if last_raise is not None and now - last_raise < interval - 1e-9:
        wait = interval - (now - last_raise)
        return schema.TorqueRaiseRefused(
            message=f"a change that can raise the torque ({what}; {peaks}) may be made at most every {interval:g} s; "
            f"the last was {now - last_raise:.2f} s ago (try again in {wait:.2f} s)",
            reason="too_soon",
            retry_after_s=round(wait, 3),
            fields=raise_.fields,
            peak_before_Nm=raise_.peak_before_Nm,
            peak_after_Nm=raise_.peak_after_Nm,
        )
    if not confirm:
        return schema.TorqueRaiseRefused(
            message=f"this change can raise the torque on the person ({what}; {peaks}): confirm it to make it",
            reason="confirm",
            retry_after_s=0.0,
            fields=raise_.fields,
            peak_before_Nm=raise_.peak_before_Nm,
            peak_after_Nm=raise_.peak_after_Nm,
        )
    return None
